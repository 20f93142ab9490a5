"""Charts and maps: the stability charts of the synchronous motions in a parameter plane,
in closed form (``stability``), and the contact-force, Taylor-error and eigenvalue maps
(``forces_map``)."""
