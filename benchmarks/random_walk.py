"""Why the MRGIA follows wear with random-walk parameters, not forgetting: the measurement behind MRGIAConfig.random_walk.

Run: ``.venv/bin/python benchmarks/random_walk.py`` (about ten seconds). Prints two tables.

1. Tracking a worn gear. The plant of the wear scenarios
   (:data:`servoid.ident.models.wear.GEAR_PLANT`: the paper's linear block and m2,
   c1 0.4, c2 0.6) driven by the paper's uniform input (|u| <= 2.406), output
   noise at SNR 40; c1 + c2 ramps from 1.0 to 1.5 over 200 000 samples
   (after 20 000 samples at 1.0, followed by 50 000 at 1.5). Every estimator
   starts from the unworn model with ``P(0) = 1e-2 I``. Two ways to keep the
   gain from vanishing: a floor on rho (``rho_exponent = 1``, so ``rho``
   reaches the floor and then forgets at ``1 - floor`` per update) and the
   random walk (``q`` added to P's diagonal per update). Reported for c1 + c2
   (:func:`ramp_figures`): the RMS error over the ramp; the lag; the
   standard deviation and the bias on the plateau.
2. Keeping P bounded. 10 000 samples of the uniform input, then 100 000 of a
   slow rising sawtooth that drops in one step (the down line is almost
   never visited: a one-sided excitation), no cap on P. Reported: the
   largest diagonal entry of P and the smallest eigenvalue over the run.
3. One q for every unit. The bench servo (rad, c1 + c2 = 0.05 rad) under
   uniform input +/-0.2 rad, noise-free, its dead zones x 1.5 at sample
   10 000: ``q = 1e-7 (c1 + c2)^2`` on the signals in rad (sized for the dead
   zones, hence tiny for the linear block), against ``q = 1e-7`` on the
   signals divided by ``c1 + c2`` (what :class:`servoid.ident.monitoring.wear_estimator.WearEstimator`
   does). Reported: c1 + c2 over its true value 140 000 samples later.
"""

from __future__ import annotations

import numpy as np

from servoid.drivers.sim import SIM_PLANTS, reference_output_std
from servoid.ident import MRGIA, MRGIAConfig, noise_epsilon, run_mrgia
from servoid.ident.models.wear import GEAR_PLANT, Wear, WearingPlant
from servoid.ident.paper import PAPER_INPUT_AMPLITUDE

SNR = 40.0
BEFORE, RAMP, AFTER = 20_000, 200_000, 100_000
PLATEAU = 80_000  # the last samples, where the estimate has caught up
SETTINGS = [("floor", 1e-3), ("floor", 3e-3), ("floor", 1e-2), ("q", 1e-8), ("q", 1e-7), ("q", 1e-6)]


def _config(kind: str, value: float, epsilon: float, **extra: object) -> MRGIAConfig:
    start = dict(theta0=tuple(GEAR_PLANT.theta), p0=1e-2, epsilon=epsilon)
    if kind == "floor":
        return MRGIAConfig(rho_exponent=1.0, rho_floor=value, **start, **extra)  # type: ignore[arg-type]
    return MRGIAConfig.random_walk(process_noise=value, **start, **extra)


def ramp_figures(k: np.ndarray, estimate: np.ndarray, truth: np.ndarray, *, total: int) -> dict[str, float]:
    """How an estimate of c1 + c2 followed the ramp of :data:`RAMP` samples from :data:`BEFORE` (``total`` samples).

    ``rms``: RMS error over the ramp; ``std``, ``bias``: scatter and mean of
    the error relative to the truth on the plateau (the last
    :data:`PLATEAU` samples); ``lag``: the mean error over the last three
    quarters of the ramp, less that relative bias times the truth, over the
    ramp's slope, in samples. (A lag and an offset look the same on a ramp;
    the estimator's bias, measured on the plateau, is proportional to the
    dead zone: -0.24 % at 1.0 and at 1.5.) Errors are in units of the
    unworn c1 + c2.
    """
    scale = truth[0]
    err = (estimate - truth) / scale
    slope = (truth[-1] - truth[0]) / scale / RAMP
    ramp = (k >= BEFORE) & (k < BEFORE + RAMP)
    late = (k >= BEFORE + RAMP // 4) & (k < BEFORE + RAMP)
    plateau = k >= total - PLATEAU
    bias = float(np.mean(err[plateau] * scale / truth[plateau]))
    return {
        "rms": float(np.sqrt(np.mean(err[ramp] ** 2))),
        "lag": -float(np.mean(err[late] - bias * truth[late] / scale)) / slope,
        "std": float(np.std(err[plateau])),
        "bias": bias,
    }


def drifting_record(seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Input, noisy output, true c1 + c2 per sample, and the noise standard deviation."""
    n = BEFORE + RAMP + AFTER
    wear = Wear(drift=1.5, drift_samples=RAMP, drift_start=BEFORE)
    rng = np.random.default_rng(seed)
    u = rng.uniform(-PAPER_INPUT_AMPLITUDE, PAPER_INPUT_AMPLITUDE, n)
    plant = WearingPlant(GEAR_PLANT, wear)
    y = np.array([plant.step(v) for v in u])
    noise = reference_output_std(SIM_PLANTS["gear"]) / SNR
    truth = np.array([wear.factor(j) for j in range(n)]) * GEAR_PLANT.dead_zone
    return u, y + rng.normal(0.0, noise, n), truth, noise


def tracking_table() -> None:
    u, y, truth, noise = drifting_record()
    eps = noise_epsilon(noise)
    n = u.size
    print(f"1. tracking c1 + c2 from 1.0 to 1.5 over {RAMP} samples, SNR {SNR:g} (noise std {noise:.4f})")
    print(
        f"   {'setting':14s} {'RMS error':>10s} {'lag':>8s} {'std':>8s} {'bias':>8s}  (lag in samples, bias relative)"
    )
    for kind, value in SETTINGS:
        res = run_mrgia(u, y, _config(kind, value, eps), record_every=100)
        k = res.history_samples
        vals = res.values_history()
        f = ramp_figures(k, vals[:, -2] + vals[:, -1], truth[k], total=n)
        name = f"{kind} {value:g}"
        print(f"   {name:14s} {f['rms']:10.4f} {f['lag']:8.0f} {f['std']:8.4f} {f['bias']:+8.4f}")
    print()


def windup_table() -> None:
    rng = np.random.default_rng(1)
    n = 100_000
    saw = (np.arange(n) % 400) / 400 * 4.8 - 2.4 + rng.uniform(-0.05, 0.05, n)
    u = np.r_[rng.uniform(-PAPER_INPUT_AMPLITUDE, PAPER_INPUT_AMPLITUDE, 10_000), saw]
    plant = WearingPlant(GEAR_PLANT, Wear())
    noise = reference_output_std(SIM_PLANTS["gear"]) / SNR
    y = np.array([plant.step(v) for v in u]) + rng.normal(0.0, noise, u.size)
    eps = noise_epsilon(noise)
    print("2. one-sided excitation (rising sawtooth after 10 000 uniform samples), P uncapped")
    print(f"   {'setting':14s} {'max diag P':>12s} {'min eig P':>12s} {'recoveries':>10s}")
    for kind, value in SETTINGS:
        est = MRGIA(_config(kind, value, eps, p_max=np.inf))
        worst, least = 0.0, np.inf
        for k in range(u.size):
            est.update(u[k], y[k])
            if k % 1000 == 999:
                P = est.P
                worst = max(worst, float(np.max(np.diag(P))))
                least = min(least, float(np.min(np.linalg.eigvalsh(P))))
        name = f"{kind} {value:g}"
        print(f"   {name:14s} {worst:12.3g} {least:12.3g} {len(est.recoveries):10d}")
    print()


def units_table() -> None:
    from servoid.drivers.model_plant import MODEL_PLANT

    n, s = 150_000, MODEL_PLANT.dead_zone
    u = np.random.default_rng(1).uniform(-0.2, 0.2, n)
    plant = WearingPlant(MODEL_PLANT, Wear(swap_at=10_000, swap_factor=1.5))
    y = np.array([plant.step(v) for v in u])
    print("3. bench servo (rad), noise-free, c1 + c2 x 1.5 at sample 10 000: estimate / truth after 140 000 samples")
    theta = MODEL_PLANT.theta
    raw = MRGIAConfig.random_walk(process_noise=1e-7 * s * s, p_max=s * s, p0=1e-2 * s * s, theta0=tuple(theta))
    normal = theta.copy()
    normal[-2:] /= s
    scaled = MRGIAConfig.random_walk(process_noise=1e-7, p0=1e-2, theta0=tuple(normal))
    for label, cfg, scale in (("q 1e-7 s^2 on rad", raw, 1.0), ("q 1e-7 on y / s (WearEstimator)", scaled, s)):
        res = run_mrgia(u / scale, y / scale, cfg)
        print(f"   {label:28s} {(res.theta[-2] + res.theta[-1]) * scale / (1.5 * s):.4f}")
    print()


if __name__ == "__main__":
    tracking_table()
    windup_table()
    units_table()
