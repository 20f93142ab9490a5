"""Around a run: what its report says about one method and its plausibility warnings
(``checks``), and the local worker processes that never outlive the command (``processes``)."""
