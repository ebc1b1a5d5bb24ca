"""How fast servoid starts: every --help, and the first and second identify, against a bare Python.

Run: ``.venv/bin/python benchmarks/startup.py [--repeat 5] [--wheel]`` (about a
minute; with ``--wheel`` two more, for the build and a second compile).

Each time is one fresh process, wall clock, the best of ``--repeat``, with
the floor measured in the same run: ``python -c pass`` (what any Python
command costs here) and, for scale, ``python -c "import numpy"`` (what a
``--help`` that loaded the numerical libraries would cost at the least).
Targets: every ``--help`` within 0.2 s. A checkout is installed editable
(``make install``), whose import hook costs tens of milliseconds on every
start; ``--wheel`` times the same from a regular install.

``identify`` runs the default (the paper's simulated servo, 5000 samples,
plots written). The *first* runs with numba's cache empty (a fresh
``NUMBA_CACHE_DIR``): it compiles the kernels and says so on stderr; the
*second* uses that cache. ``--wheel`` builds a wheel, installs it into an
empty folder (a regular, non-editable install) and repeats the identify pair
from there with numba's default cache location, so that the cache is shown
to work where a user's pip puts servoid, not only in a checkout.

The machine may be shared (two cores here, other engineers' tests): its load
is printed first; the best of the repeats is what the code costs.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from _table import table  # benchmarks/, on the path when a benchmark runs as a script

ROOT = Path(__file__).resolve().parents[1]
COMMANDS = ("identify", "diagnose", "excite", "export", "compensate", "monitor", "emulate")
#: What the command line prints when numba starts compiling (servoid.cli.COMPILE_NOTE).
COMPILE_WORD = "compiling"


def run(argv: Sequence[str], *, env: dict[str, str] | None = None, cwd: Path | None = None) -> tuple[float, str]:
    """Wall time of one process and its stderr."""
    start = time.perf_counter()
    out = subprocess.run(list(argv), capture_output=True, text=True, env=env, cwd=cwd)
    elapsed = time.perf_counter() - start
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({out.returncode}): {out.stderr.strip()[-400:]}")
    return elapsed, out.stderr


def best(argv: Sequence[str], repeat: int, **kwargs: object) -> float:
    return min(run(argv, **kwargs)[0] for _ in range(repeat))  # type: ignore[arg-type]


def servoid_command() -> list[str]:
    script = Path(sys.executable).with_name("servoid")
    return [str(script)] if script.exists() else [sys.executable, "-m", "servoid"]


def identify_pair(
    cmd: list[str], out: Path, env: dict[str, str], cwd: Path | None = None
) -> list[tuple[str, float, bool]]:
    """The first identify (empty cache) and the best of two more, with whether each announced a compile."""
    argv = [*cmd, "identify", "--out", str(out)]
    first, err = run(argv, env=env, cwd=cwd)
    rows = [("first", first, COMPILE_WORD in err)]
    later = [run(argv, env=env, cwd=cwd) for _ in range(2)]
    rows.append(("second", min(t for t, _ in later), any(COMPILE_WORD in e for _, e in later)))
    return rows


def help_rows(cmd: list[str], repeat: int, floor: float, **kwargs: object) -> list[list[str]]:
    """One row per --help: best time, over the floor, and whether it is within 0.2 s."""
    rows = []
    for name in ("", *COMMANDS):
        t = best([*cmd, *([name] if name else []), "--help"], repeat, **kwargs)
        label = f"servoid {name + ' ' if name else ''}--help"
        rows.append([label, f"{t:.3f}", f"{t - floor:.3f}", f"{t / floor:.1f}", "yes" if t <= 0.2 else "NO"])
    return rows


def install_wheel(tmp: Path) -> Path:
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp),
                    str(ROOT)], check=True, capture_output=True)  # fmt: skip
    wheel = next(tmp.glob("servoid-*.whl"))
    site = tmp / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(site), str(wheel)],
                   check=True, capture_output=True)  # fmt: skip
    return site


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=5, help="rounds per --help time, the best kept (default 5)")
    parser.add_argument("--wheel", action="store_true", help="also time identify from a non-editable wheel install")
    args = parser.parse_args()
    print(
        f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; best of {args.repeat}; {sys.version.split()[0]}"
    )
    env = dict(os.environ)
    floor = best([sys.executable, "-c", "pass"], args.repeat, env=env)
    numpy = best([sys.executable, "-c", "import numpy"], args.repeat, env=env)
    cmd = servoid_command()
    rows = [["python -c pass (floor)", f"{floor:.3f}", "-", "-", ""],
            ["python -c 'import numpy'", f"{numpy:.3f}", f"{numpy - floor:.3f}", f"{numpy / floor:.1f}", ""]]  # fmt: skip
    rows += help_rows(cmd, args.repeat, floor, env=env)
    table("--help from this checkout (an editable install), one fresh process each (s)",
          ["command", "best", "over floor", "x floor", "<= 0.2 s"], rows)  # fmt: skip

    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        ident_rows = []
        fresh = {**env, "NUMBA_CACHE_DIR": str(tmp / "numba-cache")}
        for which, t, said in identify_pair(cmd, tmp / "run", fresh):
            ident_rows.append([f"checkout, {which}", f"{t:.2f}", f"{t - floor:.2f}", "yes" if said else "no"])
        if args.wheel:
            site = install_wheel(tmp)
            wheel_env = {k: v for k, v in env.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
            wheel_env["PYTHONPATH"] = str(site)
            # the empty folder as working directory: the checkout is not on the path
            installed = [sys.executable, "-m", "servoid"]
            table("--help from the wheel install (python -m servoid), one fresh process each (s)",
                  ["command", "best", "over floor", "x floor", "<= 0.2 s"],
                  help_rows(installed, args.repeat, floor, env=wheel_env, cwd=tmp))  # fmt: skip
            for which, t, said in identify_pair(installed, tmp / "wrun", wheel_env, cwd=tmp):
                ident_rows.append([f"wheel, {which}", f"{t:.2f}", f"{t - floor:.2f}", "yes" if said else "no"])
            cached = sorted(p.name for p in (site / "servoid" / "ident" / "online" / "__pycache__").glob("*.nbi"))
            print(f"\nwheel install: numba's cache written beside the installed sources ({len(cached)} index files "
                  f"in servoid/ident/online/__pycache__)")  # fmt: skip
        shutil.rmtree(tmp / "run", ignore_errors=True)
    table("servoid identify (the paper's servo, 5000 samples, plots), one fresh process each (s)",
          ["run", "wall", "over floor", "compile announced"], ident_rows)  # fmt: skip


if __name__ == "__main__":
    main()
