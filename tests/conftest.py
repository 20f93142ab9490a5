"""Shared fixtures: the paper's Figure 3 parameters (model notes, section 6)."""

import pytest

from rubcli.model import ModelParams

FIG3 = {"nu": 0.009478, "eta": 0.7818, "e": 7.52, "K": 17.6, "Rp": 46.16, "phi0": 0.0}
FIG3_INITIAL = (0.88544, -0.8039, 0.0, 0.0)


@pytest.fixture
def fig3_params():
    def make(mu: float = 0.0, **overrides) -> ModelParams:
        return ModelParams(**{**FIG3, "mu": mu, **overrides})

    return make
