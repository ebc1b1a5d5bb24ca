"""Accuracy of the discrepancy workflow on records that hide a known effect.

For every effect of the library at two strengths, and with no effect, at
SNR 40 with 6000 training and 6000 validation samples (the paper's plant and
input, :mod:`servoid.ident.diagnosis.hidden_effects`), run :func:`servoid.ident.diagnosis.diagnose.diagnose`
without telling it the effect, and print: the effect it names, its size
estimate against the truth, the validation gap before and after, and the time
per run. Then a confusion table over several seeds, which says which effects
the workflow mixes up.

Run:  .venv/bin/python benchmarks/diagnose_hidden_effects.py [--seeds 3]
"""

from __future__ import annotations

import argparse
import time

from servoid.ident.diagnosis.diagnose import DiagnoseConfig, diagnose
from servoid.ident.diagnosis.hidden_effects import HIDDEN_STRENGTHS, hidden_effect_record
from servoid.ident.models.effects import EFFECT_NAMES, EFFECTS, NONE
from servoid.ident.online.mrgia import MRGIAConfig
from servoid.ident.paper import RECOMMENDED_RHO_EXPONENT

SAMPLES = 6000
SNR = 40.0


def cases() -> list[tuple[str, float | None]]:
    out: list[tuple[str, float | None]] = [(NONE, None)]
    for name, strengths in HIDDEN_STRENGTHS.items():
        out += [(name, v) for v in strengths]
    return out


def run_case(effect: str, value: float | None, seed: int):
    train = hidden_effect_record(effect, value, samples=SAMPLES, seed=seed, snr=SNR)
    val = hidden_effect_record(effect, value, samples=SAMPLES, seed=seed + 1000, snr=SNR)
    config = DiagnoseConfig(identification=MRGIAConfig(na=2, nb=0, delay=1, rho_exponent=RECOMMENDED_RHO_EXPONENT))
    started = time.perf_counter()
    result = diagnose(train.u, train.y, val.u, val.y, config)
    return result, time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=3, help="seeds per case (default 3)")
    args = parser.parse_args()
    header = f"{'hidden effect':17s} {'truth':>6s} {'seed':>4s}  {'named':26s} {'estimate':>9s} {'rel.err':>8s} " \
             f"{'gap before':>10s} {'gap after':>9s} {'ratio':>6s} {'time':>6s}"  # fmt: skip
    print(f"servoid diagnose on hidden-effect records: {SAMPLES} + {SAMPLES} samples, SNR {SNR:g}")
    print(header)
    print("-" * len(header))
    confusion: dict[str, dict[str, int]] = {}
    worst_ratio, times, right = 0.0, [], 0
    total = 0
    for effect, value in cases():
        for seed in range(1, args.seeds + 1):
            result, elapsed = run_case(effect, value, seed)
            times.append(elapsed)
            named = result.effect
            confusion.setdefault(effect, {}).setdefault(named, 0)
            confusion[effect][named] += 1
            total += 1
            right += named == effect
            estimate, rel = "", ""
            if effect != NONE and named == effect:
                est = result.effect_parameters[EFFECTS[effect].parameters[0]]
                estimate = f"{est:.4g}"
                rel = f"{abs(est - value) / abs(value):.1e}"  # type: ignore[operator]
            ratio = result.gap_after / result.gap_before
            if effect != NONE:
                worst_ratio = max(worst_ratio, ratio)
            shown = "+".join(result.effects) or NONE
            truth = "" if value is None else f"{value:g}"
            print(f"{effect:17s} {truth:>6s} {seed:4d}  {shown:26s} {estimate:>9s} {rel:>8s} "
                  f"{result.gap_before:10.4f} {result.gap_after:9.4f} {ratio:6.2f} {elapsed:5.1f}s", flush=True)  # fmt: skip
    print()
    print(
        f"named right: {right}/{total}; worst gap ratio after/before with an effect hidden: {worst_ratio:.2f} "
        f"(target <= 0.6); time per run: median {sorted(times)[len(times) // 2]:.1f} s, max {max(times):.1f} s"
    )
    print()
    print("confusion (rows: hidden, columns: named; counts over strengths and seeds)")
    names = list(EFFECT_NAMES)
    print(f"{'':17s} " + " ".join(f"{n[:10]:>10s}" for n in names))
    for effect in [NONE, *HIDDEN_STRENGTHS]:
        row = confusion.get(effect, {})
        print(f"{effect:17s} " + " ".join(f"{row.get(n, 0):10d}" for n in names))


if __name__ == "__main__":
    main()
