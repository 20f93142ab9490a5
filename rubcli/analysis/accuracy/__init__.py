"""How good a solution is: the reference solution of a Problem (``reference``), error
against run time over ladders of settings (``work_precision``) and the stress suite of
extreme cases run with every method (``stress``)."""
