"""When does ``flank_rebound`` fire? The horn twins with and without their rebound, the motor-side twins (issue 12).

Run: ``.venv/bin/python benchmarks/flank_rebound.py [--presets sts3215,xm430] [--rates 10,20,50] [--seeds 1,2,3]
[--damping 1,10] [--motor-side cia402,odrive] [--motor-rate 20] [--motor-seeds 1,2]``.

Each row is ``servoid.ident.identify`` as ``real_servos.py`` runs it (gentle sines, 4096 counts, 0.3 count
of noise, no structure flags) and :func:`servoid.ident.diagnosis.flank_rebound.rebound` on the answering
servo-loop model's free run (identify evaluates it on play-in-loop answers only; here it is shown for
every answer): the swing of the aligned residual as a share of the model's play, its two t statistics,
the departures, whether it is named, and identify's verdict. ``--damping 10`` runs the same twin with its
gear damping x10 (a contact that does not rebound; the twin's code is not changed, only the preset's
value passed in), the reference that the bias and the swing go together. Printed as measured.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
from _table import table
from real_servos import run, twin_record

from servoid.drivers.twin import preset
from servoid.ident.diagnosis.flank_rebound import rebound
from servoid.ident.models.effect_names import FLANK_REBOUND


def row(name: str, mult: float, seed: int, damping: float) -> list[str]:
    """One record's answer and the rebound statistic of its servo-loop model."""
    over = {} if damping == 1.0 else {"gear_damping_nms": damping * preset(name).gear_damping_nms}
    rec = twin_record(name, mult, 1.0, "sines", seed, **over)
    result, seconds = run(rec["u"], rec["y"], rec["period"])  # type: ignore[arg-type]
    head = [name, f"x{damping:g}", f"{mult:g}x", str(seed), result.structure,
            f"{100.0 * (result.play / float(rec['play']) - 1.0):+.1f} %"]  # type: ignore[arg-type]  # fmt: skip
    loop = result.loop
    if loop is None:
        return head + [
            "no loop model",
            "",
            "",
            "",
            "identifiable" if result.identifiable else "withheld",
            f"{seconds:.1f}",
        ]
    # the servo-loop model's output is about identify's operating point, as the hook reads it
    _, y_c = result.centred_point.centre(np.asarray(rec["u"]), np.asarray(rec["y"]))  # type: ignore[arg-type]
    b = rebound(y_c, np.asarray(loop.simulated), float(loop.play), float(rec["period"]))  # type: ignore[arg-type]
    doubted = any(r.startswith(FLANK_REBOUND) for r in result.verdict.reasons)
    verdict = "identifiable" if result.identifiable else "withheld"
    return head + [f"{b.swing:.3f}", f"{b.lead_t:+.1f} / {b.lag_t:+.1f}", str(b.departures),
                   "yes" if b.named else "no", verdict + (" (rebound)" if doubted else ""), f"{seconds:.1f}"]  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", default="sts3215,xm430")
    ap.add_argument("--rates", default="10,20,50")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--damping", default="1,10", help="gear damping factors of the horn twins (1: as it is)")
    ap.add_argument("--motor-side", default="cia402,odrive", help="motor-side twins ('' for none)")
    ap.add_argument("--motor-rate", type=float, default=20.0)
    ap.add_argument("--motor-seeds", default="1,2")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    rows = []
    for name in [p for p in args.presets.split(",") if p]:
        for damping in (float(d) for d in args.damping.split(",")):
            for mult in (float(r) for r in args.rates.split(",")):
                for seed in (int(s) for s in args.seeds.split(",")):
                    rows.append(row(name, mult, seed, damping))
                    print(" | ".join(rows[-1]), flush=True)
    for name in [p for p in args.motor_side.split(",") if p]:
        for seed in (int(s) for s in args.motor_seeds.split(",")):
            rows.append(row(name, args.motor_rate, seed, 1.0))
            print(" | ".join(rows[-1]), flush=True)
    table("flank_rebound on the twins' gentle sines (identify's servo-loop model)",
          ["preset", "damping", "rate", "seed", "structure", "gap", "swing / play", "t lead / lag", "departures",
           "named", "verdict", "s"], rows)  # fmt: skip


if __name__ == "__main__":
    main()
