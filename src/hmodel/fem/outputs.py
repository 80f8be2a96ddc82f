"""Files of a finite-element run: result.csv, VTU fields per saved step with a ParaView .pvd
series, fields.png and curve.png. :func:`write_result` writes them all only once the run is
over, through :func:`hmodel.io.write_outputs` (a temporary folder, then moved)."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import meshio  # noqa: E402
import numpy as np  # noqa: E402

from ..io import write_outputs  # noqa: E402
from .result import FemResult, Snapshot, material_point_curve  # noqa: E402

_CELL_TYPES = {3: "triangle", 4: "quad"}


def deviatoric_strain(eps: np.ndarray) -> np.ndarray:
    """Deviatoric strain sqrt((e11 - e22)^2 + 4 e12^2) (B,) (the diameter of Mohr's circle of
    strain; the engineering shear strain of the maximal-shear plane)."""
    return np.sqrt((eps[:, 0] - eps[:, 1]) ** 2 + 4 * eps[:, 2] ** 2)


def _point_fields(snap: Snapshot) -> dict[str, np.ndarray]:
    return {"deviatoric_strain": deviatoric_strain(snap.eps), "volumetric_strain": snap.eps[:, 0] + snap.eps[:, 1],
            "frac_sliding": snap.frac_sliding, "frac_open": snap.frac_open, "d2w_normalized": snap.d2w,
            "sig11": snap.sig[:, 0], "sig22": snap.sig[:, 1], "sig12": snap.sig[:, 2]}


def _per_element(res: FemResult, values: np.ndarray) -> np.ndarray:
    """Gauss-point values (B,) averaged over each element (volume-weighted)."""
    n = res.gauss_dx.size
    nel = res.domain.nx * res.domain.ny * (2 if res.domain.element == "t6" else 1)
    dx = res.gauss_dx.reshape(nel, n // nel)
    return np.nansum(values.reshape(nel, -1) * dx, axis=1) / dx.sum(axis=1)


def write_vtu(res: FemResult, snap: Snapshot, path: Path) -> None:
    """The vertex mesh with the displacement at vertices and element-averaged Gauss fields."""
    mesh = res.domain.mesh()
    nv = mesh.p.shape[1]
    # vertex dofs come first in scikit-fem's numbering: nodal dofs (2, n_vertices)
    u = snap.u[_vertex_dofs(res)].T if snap.u.size else np.zeros((nv, 2))
    cells = [(_CELL_TYPES[mesh.t.shape[0]], mesh.t.T)]
    data = {k: [_per_element(res, v)] for k, v in _point_fields(snap).items()}
    meshio.Mesh(np.column_stack([mesh.p.T, np.zeros(nv)]), cells,
                point_data={"displacement": np.column_stack([u, np.zeros(nv)])},
                cell_data=data).write(path, file_format="vtu")


def _vertex_dofs(res: FemResult) -> np.ndarray:
    return res.domain.basis().nodal_dofs


def write_pvd(res: FemResult, path: Path, names: list[str]) -> None:
    entries = "\n".join(f'    <DataSet timestep="{s.load:.6g}" part="0" file="{n}"/>'
                        for s, n in zip(res.snapshots, names))
    path.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n  <Collection>\n'
                    f"{entries}\n  </Collection>\n</VTKFile>\n")


def plot_fields(res: FemResult, path: Path, n_show: int = 3) -> None:
    """Rows: deviatoric strain, volumetric strain, sliding and open cells, normalized d2W per
    Gauss point; columns: ``n_show`` saved steps (the last one and evenly spread ones)."""
    snaps = res.snapshots[1:] or res.snapshots
    pick = [snaps[i] for i in np.unique(np.linspace(0, len(snaps) - 1, n_show).round().astype(int))]
    rows = [("deviatoric_strain", "viridis"), ("volumetric_strain", "coolwarm"),
            ("frac_sliding", "magma"), ("frac_open", "magma"), ("d2w_normalized", "RdBu")]
    W, H = res.domain.width, res.domain.height
    fig, axes = plt.subplots(len(rows), len(pick), figsize=(3.2 * len(pick), 2.6 * len(rows) * max(H / W, 0.6) / 1.4),
                             squeeze=False)
    x, y = res.gauss_x
    for j, snap in enumerate(pick):
        fields = _point_fields(snap)
        for i, (name, cmap) in enumerate(rows):
            ax = axes[i, j]
            v = fields[name]
            kw = {"vmin": -1, "vmax": 1} if name == "d2w_normalized" else {}
            # Gauss-point values interpolated on their Delaunay triangulation (no extrapolation
            # to the boundary: the outermost Gauss points bound the drawing)
            sc = ax.tripcolor(x, y, np.nan_to_num(v), shading="gouraud", cmap=cmap, **kw)
            ax.set_aspect("equal")
            ax.set_xticks([]), ax.set_yticks([])
            if i == 0:
                ax.set_title(_load_label(res, snap), fontsize=8)
            if j == 0:
                ax.set_ylabel(name.replace("_", " "), fontsize=8)
            cb = fig.colorbar(sc, ax=ax, fraction=0.05, format="%.3g")
            cb.ax.tick_params(labelsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _load_label(res: FemResult, snap: Snapshot) -> str:
    if res.problem == "biaxial":
        return f"step {snap.step}: eps11 = {snap.load * res.meta['axial_strain']:.3g}"
    return f"step {snap.step}: s/B = {snap.load * res.meta['settlement']:.3g}"


def plot_curve(res: FemResult, path: Path) -> None:
    """Biaxial: q and eps_v against axial strain, the FEM's against the material point's.
    Footing: the contact pressure against settlement / width."""
    if res.problem == "biaxial":
        fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
        e = res.column("eps11")
        a.plot(e, res.column("q") / 1e3, "o-", ms=3, label="FEM (reactions)")
        b.plot(e, res.column("eps_v"), "o-", ms=3, label="FEM")
        if res.reference is not None:
            c = material_point_curve(res.reference)
            a.plot(c["eps11"], c["q"] / 1e3, "k--", label="material point")
            b.plot(c["eps11"], c["eps_v"], "k--", label="material point")
        a.set_xlabel("axial strain eps11"), a.set_ylabel("q = sig11 - sig22 [kPa]")
        b.set_xlabel("axial strain eps11"), b.set_ylabel("eps_v (compression > 0)")
        a.legend(), b.legend()
        fig.suptitle(f"{res.meta['test']}, p0 = {res.meta['p0'] / 1e3:g} kPa, mesh "
                     f"{res.domain.nx}x{res.domain.ny} {res.domain.element}", fontsize=10)
    else:
        fig, a = plt.subplots(figsize=(6, 4))
        a.plot(res.column("s_B"), res.column("pressure") / 1e3, "o-", ms=3)
        a.set_xlabel("settlement / footing width"), a.set_ylabel("footing pressure [kPa]")
        a.set_title(f"strip footing, p0 = {res.meta['p0'] / 1e3:g} kPa, mesh "
                    f"{res.domain.nx}x{res.domain.ny} {res.domain.element}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_result(res: FemResult, out) -> list[Path]:
    """All outputs into ``out``, atomically."""
    names = [f"fields_{s.step:05d}.vtu" for s in res.snapshots]
    writers = {"result.csv": res.to_csv}
    for snap, name in zip(res.snapshots, names):
        writers[name] = lambda p, s=snap: write_vtu(res, s, p)
    writers["fields.pvd"] = lambda p: write_pvd(res, p, names)
    writers["fields.png"] = lambda p: plot_fields(res, p)
    writers["curve.png"] = lambda p: plot_curve(res, p)
    writers["meta.json"] = lambda p: p.write_text(json.dumps({**res.meta, "stopped": res.stopped}, indent=1))
    return write_outputs(out, writers)
