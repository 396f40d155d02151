# /// script
# requires-python = ">=3.11"
# dependencies = ["pbvs_pin"]  # from this repository: pip install .
# ///
"""Reproduce one of the paper's experiments on the reference robot and open its replay.

Runs a shipped scenario (Experiment 1 by default: the target moves on a straight line for
20 s, then stops), writes ``log.npz``, ``summary.json``, the paper's figures and a standalone
HTML replay into ``--out``, prints the figures of merit and opens the replay in a browser.

    python examples/reproduce_pioneer_cyton.py                  # full run, replay in a browser
    python examples/reproduce_pioneer_cyton.py --no-viz         # 3 s run, no figures, no browser
"""

import argparse
import webbrowser
from pathlib import Path

import pbvs_pin
from pbvs_pin.study.claims import verdict_text
from pbvs_pin.study.experiments import run_scenario

SHORT_RUN = 3.0  # simulated time of a --no-viz run [s]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiment", default="experiment1", help="shipped scenario name")
    parser.add_argument("--out", type=Path, default=Path("results/example_reproduce"))
    parser.add_argument("--no-viz", action="store_true", help="short run, no figures, no browser")
    args = parser.parse_args()

    scenario = pbvs_pin.load_scenario(args.experiment)
    if args.no_viz:
        scenario = scenario.with_values(duration=SHORT_RUN)
    replay = args.out / "replay.html"
    print(f"{scenario.name}: {scenario.description}")
    log, summary = run_scenario(scenario, args.out, html=replay, figures=not args.no_viz)

    error = log["xi"] - log["xi_d"]  # [px], shape (samples, 3)
    print(f"simulated {log['t'][-1]:.1f} s in {log.meta['wall_time']:.1f} s of wall time")
    print(f"final feature error: {abs(error[-1]).max():.2f} px")
    for name in ("max_abs_error_final_window_px", "min_clearance_m", "target_lost_samples"):
        print(f"{name}: {summary.get(name)}")  # summary.json has every figure of merit
    print(f"verdict: {verdict_text(summary)}")  # met, NOT met: <failed clauses>, not judged: <why>
    print(f"wrote {sorted(p.name for p in args.out.iterdir())} into {args.out}")
    if not args.no_viz:
        webbrowser.open(replay.resolve().as_uri())  # plays without a server


if __name__ == "__main__":
    main()
