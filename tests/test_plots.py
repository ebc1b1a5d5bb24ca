"""Plot functions return figures and leave matplotlib's backend alone (a notebook's inline backend survives them)."""

from __future__ import annotations

import subprocess
import sys
import textwrap


def test_plots_return_figures_and_never_switch_the_backend(tmp_path):
    code = textwrap.dedent(f"""
        import sys
        import matplotlib
        matplotlib.use("svg")  # stands for a notebook's backend: whatever the session chose
        import numpy as np
        from matplotlib.figure import Figure
        from servoid import plots
        from servoid.cli import main
        from servoid.ident import PAPER_PLANT, MRGIAConfig, identify, simulate

        u = np.random.default_rng(0).uniform(-2.4, 2.4, 800)
        sim = simulate(PAPER_PLANT, u)
        result = identify(sim.u, sim.y, MRGIAConfig())
        figures = [plots.plot_convergence(result.mrgia, truth=PAPER_PLANT),
                   plots.plot_fit(sim.y, {{"fit": sim.y}}, u=sim.u),
                   plots.plot_backlash(result.model, sim.x, sim.y)]
        assert all(isinstance(f, Figure) for f in figures)
        assert plots.save(figures[2], {str(tmp_path / "loop.png")!r}).stat().st_size > 0
        assert main(["identify", "--samples", "600", "--out", {str(tmp_path / "run")!r}]) == 0
        print(matplotlib.get_backend(), "matplotlib.pyplot" in sys.modules)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    # the session's backend is untouched, and pyplot (with its global list of open figures) never imported
    assert out.stdout.split()[-2:] == ["svg", "False"]
    assert (tmp_path / "run" / "fit.png").stat().st_size > 0
