"""Whether identify() may skip its second refinement start when the first already fits at the noise floor.

Run: ``.venv/bin/python benchmarks/skip_start.py [--seeds 10] [--twin-samples 6000]``.

identify() refines from the MRGIA's estimate, then from an ARX start (or the
order selection's fit), and keeps the better fit. When the first fit is
within ``SKIP_AT_FLOOR`` of the record's noise floor (``floor_nrmse``), the
second cannot fit meaningfully better and is skipped. This runs every record
both ways (the rule off: the factor 0) and prints, per record, the first
start's fit over the floor, whether the rule skipped, the play and the fit
with and without it, and the CPU time of identify() each way. Records: the
paper's example (SNR 43, 5000 samples, uniform input, seeds 0..n-1) and each
physical twin (driven as ``benchmarks/twins.py`` drives them, seed 1).
"""

from __future__ import annotations

import argparse
import importlib
import os
import time

import numpy as np
from _table import table  # benchmarks/, on the path when a benchmark runs as a script

from servoid.drivers.twin import Twin, preset, preset_names
from servoid.errors import ServoidError
from servoid.ident import PAPER_PLANT, MRGIAConfig, noise_epsilon, simulate
from servoid.ident.identify import identify

identify_module = importlib.import_module("servoid.ident.identify")  # the package's `identify` is the function

HOST_RATE_HZ = 100.0  # as benchmarks/twins.py
AMPLITUDE_RAD = 0.1


def records(seeds: int, twin_samples: int) -> list[tuple[str, np.ndarray, np.ndarray, MRGIAConfig]]:
    """The paper's example per seed, then each twin (none for 0 samples)."""
    out = []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        sim = simulate(PAPER_PLANT, rng.uniform(-2.4, 2.4, 5000), snr=43.0, rng=rng)
        out.append((f"paper seed {seed}", sim.u, sim.y, MRGIAConfig(epsilon=noise_epsilon(sim.noise_std))))
    for name in preset_names() if twin_samples else ():
        twin = Twin(preset(name), seed=1)
        twin.enable()
        u = np.random.default_rng(1).uniform(-AMPLITUDE_RAD, AMPLITUDE_RAD, twin_samples)
        rec = twin.sample(u, 1.0 / HOST_RATE_HZ)
        out.append((name, rec.u, rec.y, MRGIAConfig()))
    return out


def run(u: np.ndarray, y: np.ndarray, config: MRGIAConfig, factor: float) -> tuple[object, float]:
    """identify() with the skip factor set, and its CPU time."""
    saved = identify_module.SKIP_AT_FLOOR
    identify_module.SKIP_AT_FLOOR = factor
    try:
        t0 = time.process_time()
        result = identify(u, y, config)
        return result, time.process_time() - t0
    finally:
        identify_module.SKIP_AT_FLOOR = saved


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="seeds of the paper's example (default 10)")
    parser.add_argument("--twin-samples", type=int, default=6000, help="host samples per twin (default 6000)")
    args = parser.parse_args()
    factor = identify_module.SKIP_AT_FLOOR
    rows, saved, total = [], 0.0, 0.0
    first_u, first_y, first_config = records(1, 0)[0][1:]
    run(first_u, first_y, first_config, factor)  # compiled before the clocks start
    for name, u, y, config in records(args.seeds, args.twin_samples):
        try:
            off, t_off = run(u, y, config, 0.0)
            on, t_on = run(u, y, config, factor)
        except ServoidError as exc:  # the same record fails either way: say so and go on
            rows.append([name, "failed", str(exc)[:60]] + [""] * 8)
            continue
        first = next(iter(off.start_nrmse.values()))  # type: ignore[attr-defined]
        skipped = len(on.start_nrmse) < len(off.start_nrmse)  # type: ignore[attr-defined]
        p_off, p_on = off.model.dead_zone, on.model.dead_zone  # type: ignore[attr-defined]
        rows.append([name, f"{first / off.floor_nrmse:.3f}", "yes" if skipped else "no",  # type: ignore[attr-defined]
                     f"{p_off:.6g}", f"{p_on:.6g}", f"{abs(p_on - p_off) / p_off:.1e}",
                     f"{off.fit_nrmse:.5f}", f"{on.fit_nrmse:.5f}",  # type: ignore[attr-defined]
                     f"{off.refined_from}", f"{t_off:.2f}", f"{t_on:.2f}"])  # type: ignore[attr-defined]  # fmt: skip
        saved += t_off - t_on
        total += t_off
    table(f"identify() with and without skipping the second start at fit <= {factor:g} x floor "
          f"(load average {os.getloadavg()[0]:.2f}; CPU time saved {saved:.1f} s of {total:.1f} s, "
          f"{100 * saved / total:.0f} %)",
          ["record", "1st fit/floor", "skipped", "play off", "play on", "rel. change", "fit off", "fit on",
           "best start off", "s off", "s on"], rows)  # fmt: skip


if __name__ == "__main__":
    main()
