"""Write a training and a validation recording whose plant hides an effect, for ``servoid diagnose``.

    python examples/hidden_effect.py dead_zone 0.3 --out runs/hidden
    servoid diagnose --train runs/hidden/train.csv --validate runs/hidden/validate.csv --na 2 --nb 0 --delay 1

The plant is the paper's (Section 4) with the named effect of the library
added, driven by the paper's uniform input, 6000 samples each, SNR 40
(:func:`servoid.ident.diagnosis.hidden_effects.hidden_effect_record`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from servoid.ident.diagnosis.hidden_effects import hidden_effect_record
from servoid.ident.models.effects import EFFECT_NAMES, NONE
from servoid.recording import write_recording


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("effect", choices=EFFECT_NAMES)
    parser.add_argument("value", type=float, nargs="?", help="its parameter (omit for none)")
    parser.add_argument("--samples", type=int, default=6000)
    parser.add_argument("--snr", type=float, default=40.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("runs/hidden"))
    args = parser.parse_args()
    if args.effect != NONE and args.value is None:
        parser.error(f"{args.effect} needs a value")
    for name, seed in (("train.csv", args.seed), ("validate.csv", args.seed + 1000)):
        rec = hidden_effect_record(args.effect, args.value, samples=args.samples, seed=seed, snr=args.snr)
        path = write_recording(
            args.out / name,
            {"t": 0.01 * np.arange(args.samples), "u": rec.u, "y": rec.y},
            metadata={"source": f"paper plant + {args.effect} {args.value}", "unit": "unit"},
        )
        print(path)


if __name__ == "__main__":
    main()
