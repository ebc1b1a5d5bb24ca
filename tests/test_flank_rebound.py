"""``flank_rebound``: the horn bouncing off the flank after reversals, named by diagnose and doubted by identify.

The records are the STS3215 twin's (the loop closed around the play, encoder on the horn) under
gentle sines at 20x its loop bandwidth: its horn rebounds off the gear's lightly damped contact.
The same twin with the gear's damping x10 does not rebound; the servo-loop model's own massless
simulation has nothing to rebound.
"""

import json

import numpy as np
import pytest

from servoid.errors import DataError
from servoid.ident import MRGIAConfig, identify
from servoid.ident.diagnosis.diagnose import DiagnoseConfig, diagnose
from servoid.ident.diagnosis.flank_rebound import MIN_SWING, rebound
from servoid.ident.identify import SELECTABLE
from servoid.ident.models.effect_names import FLANK_REBOUND
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.models.structure_names import PLAY_IN_LOOP

#: 20x the STS3215 twin's loop bandwidth (7 Hz), s.
PERIOD = 1.0 / 140.0
#: Record length, s (about 50 reversals).
SECONDS = 20.0
#: The black box's candidates tried (one keeps the test short; the loop's effects do not depend on them).
CONFIG = DiagnoseConfig(identification=MRGIAConfig(), candidates=("coulomb_friction",), max_effects=1)


def _sts3215(seed: int, damping: float) -> tuple[np.ndarray, np.ndarray]:
    """Gentle sines on the STS3215 twin (4096 counts, 0.3 count of noise), its gear damping scaled by ``damping``."""
    from servoid.drivers.twin import Twin, preset
    from servoid.excitation.generate import sample
    from servoid.excitation.specs import GentleSpec

    base = preset("sts3215")
    twin = Twin(preset("sts3215", load_encoder_cpr=4096, encoder_noise_counts=0.3,
                       gear_damping_nms=base.gear_damping_nms * damping), seed=seed)  # fmt: skip
    twin.enable()
    u = sample(GentleSpec(amplitude=0.1, accel=8.0 * PERIOD**2, spread=8.0), int(SECONDS / PERIOD), seed=seed + 1000)
    rec = twin.sample(u, PERIOD)
    return np.asarray(rec.u, dtype=float), np.asarray(rec.y, dtype=float)


@pytest.fixture(scope="module", params=[1.0, 10.0], ids=["as-is", "damped-x10"])
def sts3215(request):
    damping = request.param
    return damping, _sts3215(1, damping), _sts3215(2, damping)


def test_diagnose_names_the_rebound_on_the_horn_twin_and_not_with_the_gear_damped(sts3215):
    damping, train, val = sts3215
    result = diagnose(*train, *val, CONFIG, sample_period_s=PERIOD)
    loop = result.loop
    assert loop is not None and loop.rebound is not None
    obj = json.loads(json.dumps(result.to_dict(), allow_nan=False))
    if damping == 1.0:
        assert loop.rebounds and FLANK_REBOUND in result.effects
        assert loop.rebound.swing >= MIN_SWING and obj["loop_effect"]["rebound"]["named"] is True
        assert FLANK_REBOUND in loop.rebound_line() and "biased" in loop.rebound_line()
    else:
        assert not loop.rebounds and FLANK_REBOUND not in result.effects
        assert loop.rebound.swing < MIN_SWING and obj["loop_effect"]["rebound"]["named"] is False


def test_identify_doubts_a_play_in_the_loop_whose_load_rebounds(sts3215):
    damping, train, _ = sts3215
    result = identify(*train, MRGIAConfig(), select=SELECTABLE, sample_period_s=PERIOD)
    said = [r for r in result.verdict.reasons if r.startswith(FLANK_REBOUND)]
    assert result.structure == PLAY_IN_LOOP
    if damping == 1.0:
        assert len(said) == 1 and not result.identifiable and "biased" in said[0]
    else:
        assert not said


def _massless(noise: float, seed: int = 3) -> tuple[np.ndarray, np.ndarray, ServoLoopModel]:
    """The servo-loop model's own massless simulation of gentle sines (the play in the loop), plus white noise."""
    from servoid.excitation.generate import sample
    from servoid.excitation.specs import GentleSpec

    model = ServoLoopModel(structure=PLAY_IN_LOOP, sample_period_s=PERIOD, kp=30.0, kv=150.0, c1=0.0015, c2=0.0015)
    u = sample(GentleSpec(amplitude=0.1, accel=8.0 * PERIOD**2, spread=8.0), int(SECONDS / PERIOD), seed=seed)
    y_hat = model.simulate(u)
    return y_hat + np.random.default_rng(seed).normal(0.0, noise, u.size), y_hat, model


def test_a_massless_load_is_not_named():
    y, y_hat, model = _massless(0.3 * 2.0 * np.pi / 4096)
    quiet = rebound(y, y_hat, model.play, PERIOD)
    assert quiet.departures >= 30 and not quiet.named and abs(quiet.swing) < MIN_SWING


def test_too_few_departures_or_no_play_name_nothing_and_json_has_no_nan():
    y, y_hat, model = _massless(0.0)
    few = rebound(y[:300], y_hat[:300], model.play, PERIOD)
    assert not few.named and not np.isfinite(few.swing)
    assert not rebound(y, y_hat, 0.0, PERIOD).named
    json.dumps(few.to_dict(), allow_nan=False)


def test_records_of_different_lengths_are_refused_in_one_line():
    y, y_hat, model = _massless(0.0)
    with pytest.raises(DataError, match="y_hat has 10 samples"):
        rebound(y, y_hat[:10], model.play, PERIOD)
