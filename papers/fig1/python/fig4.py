"""Redraw Fig. 4 of the servicing scenario (topologies/fig1.toml): each servicer's tracking error
‖eᵢ‖ against time, log axis, from a run directory's plant telemetry (columns ``a<i>_e_norm_m``).

    PYTHONPATH=python python3 papers/fig1/python/fig4.py RUN_DIR [OUT.png]   (or after pip install ./python)

Without matplotlib it prints the last value of each series and draws nothing.
"""

import os
import sys

import cohort


def series(run):
    plant = run["plant"]
    t = plant.column("t_s").to_pylist()
    names = [n for n in plant.column_names if n.startswith("a") and n.endswith("_e_norm_m")]
    if not names:
        raise SystemExit(f"{run.run_dir}: the plant telemetry has no a<i>_e_norm_m columns (not a fig1 run?)")
    return t, {n: plant.column(n).to_pylist() for n in sorted(names, key=lambda n: int(n[1:n.index("_")]))}


def main(argv):
    if len(argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    run = cohort.load(argv[1])
    out = argv[2] if len(argv) > 2 else os.path.join(argv[1], "plots", "fig4_python.png")
    t, es = series(run)
    unit = run.unit("plant", next(iter(es)))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: not drawing; last values:")
        for name, e in es.items():
            print(f"  {name} = {e[-1]} {unit}")
        return 0
    fig, ax = plt.subplots(figsize=(10, 5.5))
    for name, e in es.items():
        ax.semilogy(t, [max(v, 1e-9) for v in e], lw=0.8, label=f"servicer {name[1:name.index('_')]}")
    ax.axhline(5.0, color="k", ls="--", lw=0.8, label="paper: ≈ 5 m after 200 s")
    ax.set_xlabel(f"t [{run.unit('plant', 't_s')}]")
    ax.set_ylabel(f"‖eᵢ‖ [{unit}]")
    ax.set_title("Fig. 4: tracking error")
    ax.legend(fontsize=8)
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
