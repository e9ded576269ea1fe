"""The nominal model's evaluations shared by the arm diagnosers at a sample (robofdi.observers.evaluations): the
memo gives Pinocchio's values bit for bit, recomputes when the arguments change, and takes an unchanging array (a
read-only one that owns its memory) again by identity."""
import numpy as np

from robofdi import ASSETS
from robofdi.models import ManipulatorModel
from robofdi.observers.evaluations import Evaluations


def _readonly(a):
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


def test_the_memo_gives_the_models_values_and_follows_its_arguments():
    model = ManipulatorModel(ASSETS / "arm6.xml")
    ev, n = Evaluations(model), model.n
    rng = np.random.default_rng(4)
    x, tau = rng.uniform(-1, 1, 2 * n), rng.uniform(-20, 20, n)
    q, v = x[:n], x[n:]
    for got, want in ((ev.mass_matrix_at(x), model.mass_matrix(q)), (ev.gravity_at(x), model.gravity(q)),
                      (ev.coriolis_at(x), model.coriolis(q, v)), (ev.acceleration_at(x, tau), model.acceleration(q, v, tau))):
        assert got.tobytes() == want.tobytes() and not got.flags.writeable
    assert ev.mass_matrix(q) is ev.mass_matrix_at(x)            # one memo, whichever form asked
    before = ev.mass_matrix_at(x)
    x[0] += 0.3                                                 # a writeable argument changed in place: recomputed
    after = ev.mass_matrix_at(x)
    assert after is not before and after.tobytes() == model.mass_matrix(x[:n]).tobytes()
    assert ev.acceleration_at(x, tau).tobytes() == model.acceleration(x[:n], x[n:], tau).tobytes()


def test_an_unchanging_argument_is_a_hit_by_identity_and_a_new_one_by_its_bytes():
    model = ManipulatorModel(ASSETS / "arm6.xml")
    ev, n = Evaluations(model), model.n
    x, tau = _readonly(np.linspace(-0.5, 0.5, 2 * n)), _readonly(np.full(n, 3.0))
    first = ev.acceleration_at(x, tau)
    assert ev._acceleration[2] == (x, tau)                     # kept for the identity test
    assert ev.acceleration_at(x, tau) is first
    same_values = _readonly(x)                                 # another object, the same bytes: still the memo's value
    assert ev.acceleration_at(same_values, tau) is first
    other = _readonly(x + 1e-3)
    assert ev.acceleration_at(other, tau).tobytes() == model.acceleration(other[:n], other[n:], tau).tobytes()
    writeable = np.array(x)                                    # not unchanging: never kept for identity
    ev.mass_matrix_at(writeable)
    assert ev._mass[2] is None
