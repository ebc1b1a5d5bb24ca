"""Turn the shared real-data files into servoid recordings and diagnose them.

    python examples/real_data.py emps [--data ../shared/data] [--out runs/emps]
    python examples/real_data.py xl330 [--data ../shared/data] [--out runs/xl330]

emps
    EMPS benchmark: training DATA_EMPS.mat, validation DATA_EMPS_PULSES.mat
    (same reference, plus force pulses), u = qg, y = qm [m], decimated 1 kHz
    -> 100 Hz; base model na = 2, nb = 1, delay = 1.
xl330
    Dynamixel XL330 pendulum log (BAM): u = goal position, y = position
    [rad], ~189 Hz; first 67 % for training, the rest for validation; base
    model na = 2, nb = 0, delay = 1.

Each writes train.csv and validate.csv (servoid's recording format) into
--out, then runs ``servoid diagnose`` on them (same options as printed), so
the commands can be repeated by hand.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from servoid.cli import main as servoid_main
from servoid.readers import read_bam, read_emps

SETTINGS = {
    "emps": {"na": 2, "nb": 1, "delay": 1, "decimate": 10},
    "xl330": {"na": 2, "nb": 0, "delay": 1, "decimate": 1, "train_fraction": 0.67},
}


def convert(which: str, data: Path, out: Path) -> tuple[Path, Path]:
    """Write train.csv and validate.csv for ``which`` into ``out``."""
    s = SETTINGS[which]
    if which == "emps":
        train = read_emps(data / "emps" / "DATA_EMPS.mat", decimate=s["decimate"])
        validate = read_emps(data / "emps" / "DATA_EMPS_PULSES.mat", decimate=s["decimate"])
    else:
        log = read_bam(data / "bam" / "bam_xl330_raw_2026-01-15_10h28m10.json", decimate=s["decimate"])
        train, validate = log.split(s["train_fraction"])
    return train.to_csv(out / "train.csv"), validate.to_csv(out / "validate.csv")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("which", choices=sorted(SETTINGS))
    parser.add_argument(
        "--data",
        type=Path,
        default=Path(__file__).resolve().parents[1].parent / "shared" / "data",
        help="the shared data folder (default ../shared/data beside the repository)",
    )
    parser.add_argument("--out", type=Path, help="output folder (default runs/<which>)")
    parser.add_argument("--json", action="store_true", help="print the diagnosis as one JSON object")
    args = parser.parse_args()
    out = args.out or Path("runs") / args.which
    train, validate = convert(args.which, args.data, out)
    s = SETTINGS[args.which]
    argv = [
        "diagnose",
        "--train",
        str(train),
        "--validate",
        str(validate),
        "--na",
        str(s["na"]),
        "--nb",
        str(s["nb"]),
        "--delay",
        str(s["delay"]),
        "--rho-exponent",
        "0.75",
        "--out",
        str(out),
    ]
    if args.json:
        argv.append("--json")
    print("servoid " + " ".join(argv), file=sys.stderr)
    return servoid_main(argv)


if __name__ == "__main__":
    sys.exit(main())
