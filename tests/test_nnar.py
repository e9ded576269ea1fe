"""The book's NNAR (Leuschen, Walker & Cavallaro, Sec. 9): linear AR's null space Ω applied to the nonlinear
equations; on the wheel actuator its tests equal the NLAR tests (Sec. 5 footnote), symbolically and on a rig run."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from robofdi import RobofdiError
from robofdi.models.hydraulic import CATALOGUE, hydraulic_domain, hydraulic_model
from robofdi.redundancy.baselines import linear_ar_design, nnar_design
from robofdi.redundancy.nlar import derive_nlar
from robofdi.redundancy.nnar import derive_nnar, linear_null_space
from robofdi.systems.hydraulic import HydraulicScenario, nominal_operating_point, run_scenario


@pytest.fixture(scope="module")
def designs():
    m = hydraulic_model()                   # the load-compensated model the system uses
    nl = derive_nlar(m, hydraulic_domain(m))
    lin = linear_ar_design(CATALOGUE, *nominal_operating_point())
    return nl, lin, derive_nnar(nl, lin)


def test_linear_null_space_is_constant_and_annihilates_the_linear_observability(designs):
    _, lin, _ = designs
    omega = linear_null_space(lin)
    G = np.array(lin.observability.jacobian(sp.Matrix(lin.model.states)), dtype=float)
    assert omega.shape == (5, 6) and np.abs(omega @ G).max() < 1e-9 * np.abs(G).max()
    assert np.linalg.matrix_rank(omega) == 4                 # the trivial R3 (y2 vs y2) is a zero row
    assert not omega[2].any()


def test_nnar_equals_nlar_on_the_wheel_actuator(designs):
    """Same rows and pivots: every Ω_lin row is e_i − Σ α e_pivot and the pivot rows' equation residuals vanish."""
    nl, _, nn = designs
    assert nn.independent == nl.independent == ["R1", "R2", "R4", "R5"] and nn.trivial == ["R3"]
    for name in nn.independent:
        assert sp.simplify(nn.tests[name] - nl.tests[name]) == 0, name


def test_nnar_does_not_depend_on_the_linearisation_point_here(designs):
    nl, _, nn = designs
    other = nnar_design(nl, CATALOGUE, 0.5, 4e6)
    assert not np.allclose(np.array(other.omega, dtype=float), np.array(nn.omega, dtype=float))
    for name in nn.independent:
        assert sp.simplify(other.tests[name] - nl.tests[name]) == 0


def test_nnar_of_a_linear_model_is_linear_ar(designs):
    """Applying Ω_lin to the linear model's own equations gives back linear AR: the relation NNAR reuses."""
    _, lin, _ = designs
    again = derive_nnar(lin, lin)
    for name in lin.independent:
        diff = sp.expand(again.tests[name] - lin.tests[name])
        assert all(abs(float(c)) < 1e-9 * max(1.0, abs(float(c0)))
                   for c, c0 in zip(sp.Poly(diff, *diff.free_symbols).coeffs() if diff.free_symbols else [diff],
                                    sp.Poly(lin.tests[name], *lin.tests[name].free_symbols).coeffs()))


def test_nnar_residuals_equal_nlar_residuals_on_a_rig_run():
    sc = HydraulicScenario("probe", duration=1.0, diagnosers=("nlar", "nnar"))
    rec = run_scenario(sc, None)
    a, b = rec.diagnosers["nlar"].residual, rec.diagnosers["nnar"].residual
    assert rec.diagnosers["nnar"].components == ["R1", "R2", "R4", "R5"]
    assert np.abs(a).max() > 0
    assert np.max(np.abs(b - a) / np.abs(a).max(axis=0)) < 1e-9       # round-off of two generated codes


def test_a_nonlinear_design_is_no_linear_ar(designs):
    nl, lin, _ = designs
    with pytest.raises(RobofdiError, match="is not linear"):
        linear_null_space(nl)
    other = derive_nlar(hydraulic_model(load_model="none"), hydraulic_domain(hydraulic_model(load_model="none")))
    with pytest.raises(RobofdiError, match="outputs and inputs"):
        derive_nnar(other, lin)
