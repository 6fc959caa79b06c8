#!/usr/bin/env python3
"""Fit the FSLIP <-> robot regression (paper §III-A) for flywheels I/II/III and write
ros_ws/src/fslip_planner/fslip_planner/data/fslip_regression.json.

    .venv/bin/python scripts/fit_fslip_regression.py [--n 15] [--plot K_I.png]
"""
import argparse
import json
import sys

import numpy as np

from fslip_planner import regression


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--n", type=int, default=15, help="standing configurations per flywheel")
    ap.add_argument("--out", default=regression.DATA_FILE)
    ap.add_argument("--plot", default=None, help="PNG with K(L) and I(L) (samples + fits)")
    a = ap.parse_args(argv)
    doc = regression.compute_all(n=a.n)
    with open(a.out, "w") as f:
        json.dump(doc, f, indent=1)
    for fw, e in doc["flywheels"].items():
        print(f"flywheel {fw}: L in [{e['L_min']:.3f}, {e['L_max']:.3f}] m")
        for k, v in e["fits"].items():
            print(f"  {k:6s} [{v['min']:.4g}, {v['max']:.4g}]  R2={v['r2']:.6f}  max rel err={v['max_rel_err']:.2e}")
    print(f"wrote {a.out}")
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(1, 2, figsize=(10, 4))
        for fw, e in doc["flywheels"].items():
            L = np.array(e["samples"]["L"])
            Lf = np.linspace(L.min(), L.max(), 200)
            for i, q in enumerate(("K", "I")):
                ax[i].plot(L, e["samples"][q], "o", ms=4)
                ax[i].plot(Lf, np.polyval(e["fits"][q]["coeffs"], Lf), "-", label=f"flywheel {fw}")
        ax[0].set(xlabel="L (m)", ylabel="K (N/m)", title="leg stiffness K(L)")
        ax[1].set(xlabel="L (m)", ylabel="I (kg m^2)", title="centroidal pitch inertia I(L)")
        ax[1].legend()
        fig.tight_layout()
        fig.savefig(a.plot, dpi=100)
        print(f"wrote {a.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
