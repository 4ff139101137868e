"""Figures of the tunnel study's worst cases, and the numbers behind its qualitative picture.

    python studies/figures.py [results/tunnel-fault.nc] [-o results]

writes `tunnel-slip.png` (slip and contact pressure along both fault parts) and
`tunnel-stress.png` (von Mises stress near the tunnel on the deformed mesh) and prints
what they show. `picture(ds)` returns the numbers (used by tests/acceptance/test_validate_studies.py):
the fault slips, stresses concentrate at the tunnel wall.

The tunnel centre is the origin, the fault the line through it along FAULT_DIR (see
studies/tunnel-fault.yaml); position along the fault is the signed distance from the
centre (west part < 0, east part > 0).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402
from matplotlib.tri import Triangulation  # noqa: E402

FAULT_DIR = np.array([120.0, 80.0]) / np.hypot(120.0, 80.0)     # (-60, -40) -> (60, 40)
TUNNEL_RADIUS = 5.0
NEAR = 8.0                                                       # "next to the tunnel": r < 8 m
INNER = 30.0                                                     # r < 30 m: the rock around the tunnel
ZOOM = 15.0                                                      # half width of the stress figure [m]


def _cell_centres(ds):
    p, t = ds["coords"].values, ds["cells"].values
    return p[t].mean(axis=1)


def _cell_areas(ds):
    p, t = ds["coords"].values, ds["cells"].values
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    return 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def _fields(ds: xr.Dataset, criterion: str):
    """The worst case of `criterion` of a run file (`worst_` fields) or the fields of a solve file."""
    if "criterion" in ds.dims and "worst_displacement" in ds:
        f = ds.sel(criterion=criterion)
        return xr.Dataset({k[len("worst_"):]: f[k] for k in f.data_vars if k.startswith("worst_")})
    return ds


def picture(ds: xr.Dataset, criterion: str = "shear") -> dict:
    """The numbers of the seed's qualitative picture at the worst case of `criterion`."""
    f = _fields(ds, criterion)
    out = {"criterion": criterion}
    pair = np.asarray(ds["contact_pair"].values).astype(str)
    slip = np.abs(f["contact_slip"].values)
    pres = f["contact_pressure"].values
    us = max(float(np.abs(f["displacement"].values).max()), 1e-300)
    for name in sorted(set(pair)):
        m = pair == name
        out[f"max_slip_{name}"] = float(slip[m].max())
        out[f"slipping_share_{name}"] = float(np.mean(slip[m] > 1e-6 * us))
        out[f"max_pressure_{name}"] = float(pres[m].max())
    c = _cell_centres(ds)
    r = np.hypot(c[:, 0], c[:, 1])
    near = r < NEAR
    area = _cell_areas(ds)
    i2 = f["shear_stress_intensity"].values
    vm = f["von_mises"].values
    out["max_I2_near"] = float(i2[near].max())
    out["mean_I2_elsewhere"] = float(np.sum(i2[~near] * area[~near]) / np.sum(area[~near]))
    out["I2_ratio"] = out["max_I2_near"] / out["mean_I2_elsewhere"]
    k = int(np.argmax(vm))
    out["max_von_mises"] = float(vm[k])
    out["max_von_mises_at"] = (float(c[k, 0]), float(c[k, 1]))
    out["max_von_mises_r"] = float(r[k])
    out["max_von_mises_near_wall"] = bool(r[k] < NEAR)
    # the rock around the tunnel, clear of the outer boundary: its corners carry
    # singularities of the boundary conditions (a pinned side meeting a loaded one, the
    # fault's ends) whose influence reaches >10 m inwards (seen: 18.2 MPa at (49, 48))
    inner = r < INNER
    ki = np.flatnonzero(inner)[int(np.argmax(vm[inner]))]
    out["max_von_mises_inner"] = float(vm[ki])
    out["max_von_mises_inner_at"] = (float(c[ki, 0]), float(c[ki, 1]))
    out["max_von_mises_inner_r"] = float(r[ki])
    out["max_von_mises_near"] = float(vm[near].max())
    out["max_von_mises_inner_elsewhere"] = float(vm[inner & ~near].max())
    far = r > 3 * NEAR
    out["mean_von_mises_far"] = float(np.sum(vm[far] * area[far]) / np.sum(area[far]))
    return out


def slip_figure(ds: xr.Dataset, path: Path) -> Path:
    pair = np.asarray(ds["contact_pair"].values).astype(str)
    xy = ds["contact_coords"].values
    s = xy @ FAULT_DIR
    fig, axes = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    styles = {"convergence": "-", "shear": "--"}
    colours = {"fault_west": "#1f77b4", "fault_east": "#d62728"}
    crits = list(map(str, ds["criterion"].values)) if "worst_displacement" in ds else ["nominal"]
    for crit in crits:
        f = _fields(ds, crit)
        for name in sorted(set(pair)):
            m = np.flatnonzero(pair == name)
            o = m[np.argsort(s[m])]
            lab = f"{name}, worst case of {crit}"
            axes[0].plot(s[o], 1e3 * f["contact_slip"].values[o], styles.get(crit, "-"),
                         color=colours.get(name), label=lab)
            axes[1].plot(s[o], 1e-6 * f["contact_pressure"].values[o], styles.get(crit, "-"),
                         color=colours.get(name), label=lab)
    for ax in axes:
        ax.axvspan(-TUNNEL_RADIUS, TUNNEL_RADIUS, color="0.85", zorder=0)
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.grid(alpha=0.3)
    axes[0].text(0, axes[0].get_ylim()[1], "tunnel", ha="center", va="top", fontsize=8)
    axes[0].set_ylabel("slip (relative tangential displacement) [mm]")
    axes[1].set_ylabel("contact pressure [MPa]")
    axes[1].set_xlabel("position along the fault from the tunnel centre [m] (west < 0 < east)")
    axes[0].legend(fontsize=7, loc="best")
    axes[0].set_title(f"{ds.attrs.get('study', '')}: the fault at the worst cases")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def stress_figure(ds: xr.Dataset, path: Path, criterion: str = "shear") -> tuple[Path, float]:
    f = _fields(ds, criterion)
    p, t = ds["coords"].values, ds["cells"].values
    u = f["displacement"].values
    c = p[t].mean(axis=1)
    window = np.all(np.abs(c) < ZOOM * 1.2, axis=1)
    tw = t[window]
    nodes = np.unique(tw)
    rel = u[nodes] - u[nodes].mean(axis=0)          # the column's settlement taken out
    mag = 10.0                                       # as the seed's figures (enlarging factor 10)
    big = np.abs(rel).max()
    if big * mag > 0.15 * ZOOM:                      # keep the picture readable
        mag = 0.15 * ZOOM / big
    q = p.copy()
    q[nodes] = p[nodes] + mag * rel
    vm = 1e-6 * f["von_mises"].values[window]
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.6), layout="constrained")
    for ax, pts, title in ((axes[0], p, "undeformed mesh"),
                           (axes[1], q, f"deformed (displacement relative to the window's mean, ×{mag:.3g})")):
        tri = Triangulation(pts[:, 0], pts[:, 1], tw)
        im = ax.tripcolor(tri, facecolors=vm, cmap="magma_r", vmin=0.0, vmax=float(vm.max()))
        ax.triplot(tri, color="k", lw=0.12, alpha=0.5)
        ax.plot(ZOOM * FAULT_DIR[0] * np.array([-2, 2]), ZOOM * FAULT_DIR[1] * np.array([-2, 2]),
                color="#1f77b4", lw=0.8, ls=":", label="fault (undeformed)")
        ax.set_xlim(-ZOOM, ZOOM)
        ax.set_ylim(-ZOOM, ZOOM)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(title, fontsize=9)
    fig.colorbar(im, ax=axes, shrink=0.8, label="von Mises stress [MPa]")
    info = picture(ds, criterion)
    x0, y0 = info["max_von_mises_inner_at"]
    axes[0].plot([x0], [y0], "c*", ms=12, label=f"max away from the outer boundary {info['max_von_mises_inner'] / 1e6:.1f} MPa")
    xg, yg = info["max_von_mises_at"]
    axes[0].plot([], [], " ", label=f"(whole mesh: {info['max_von_mises'] / 1e6:.1f} MPa at ({xg:.0f}, {yg:.0f}) m, a corner)")
    axes[0].legend(fontsize=7, loc="lower right")
    fig.suptitle(f"{ds.attrs.get('study', '')}: von Mises stress near the tunnel, worst case of {criterion}")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path, mag


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="?", default="results/tunnel-fault.nc")
    ap.add_argument("-o", "--outdir", default="results")
    a = ap.parse_args(argv)
    out = Path(a.outdir)
    out.mkdir(parents=True, exist_ok=True)
    with xr.open_dataset(a.results, engine="h5netcdf") as ds:
        ds = ds.load()
    slip_png = slip_figure(ds, out / "tunnel-slip.png")
    stress_png, mag = stress_figure(ds, out / "tunnel-stress.png")
    print(f"wrote {slip_png} and {stress_png}")
    crits = list(map(str, ds["criterion"].values)) if "worst_displacement" in ds else ["nominal"]
    for crit in crits:
        info = picture(ds, crit)
        print(f"worst case of {crit}:")
        for k, v in info.items():
            if k != "criterion":
                print(f"  {k}: {v:.4g}" if isinstance(v, float) else f"  {k}: {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
