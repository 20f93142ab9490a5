"""The response of a run: classification from the stroboscopic section (``classification``,
its evidence ``section_map``), the whirl's spectrum (``spectrum``), order tracking of a run
whose speed changes (``order_tracking``), and the orbit panels and response runs of
`compare` and `run` (``panels``)."""
