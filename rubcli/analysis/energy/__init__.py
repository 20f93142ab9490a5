"""Energy balances, the reference-free check of a solution's quality: the rigid stator's
(``balance``, its compiled core ``kernel``), a run whose speed changes (``transient``,
with the drive's torques ``drive_torques``), a stator with its own mass (``two_body``),
and a solution cut into its smooth pieces between events (``regimes``)."""
