"""Carrying bi-hexagons that turn towards the major compression: a probe of a fabric mechanism
(issue 54, docs/notes/2026-12-07-fabric-turn.md). Not an option of the cell: the rule runs here,
on the generic loading driver, one material point at a time, so that its figures can be
reproduced before it is compiled into the 3D trial.

**The rule.** The 3D REV's bi-hexagons have fixed directions n_c and weights w_c (eq. 1.17
lifted, docs/model3d.md). After every committed increment Δε of a point, each bi-hexagon that
carries (N1 above 1 % of the REV's weighted mean in either hexagon, as
``benchmarks.model3d.carrying_census``) and is inclined by θ_c to the major principal direction
of compression of Δε hands the fraction

    f_c = min(κ |Δε_I - Δε_III| sin² θ_c, 1/2)

of its weight to the direction of the sphere nearest to n_c turned by δ (default 15°) towards
that axis, most inclined cells first (where the two largest principal increments are equal, as in
triaxial extension, towards n_c's projection on their plane). The receiving cell's fields become the weighted mean of
its own and the given part's, so Σ_c w_c x_c is unchanged for every field x (forces, lengths,
angles) and Σ_c w_c stays 1. κ is a rate (one parameter, phenomenological: not derived from the
grains); κ = 0 is the REV as it is.

Why: the stress of a 3D REV is Σ_c w_c (Vσ)_c e_k ⊗ e_k / V. At the end of a drained test every
carrying bi-hexagon of the sand variant holds σ_nn/σ_tt ≈ 3 at α ≈ 64° whatever its initial
packing, so the REV's q/p is set by which directions carry: near-axial ones in a dense REV
(q/p about 1), a fan 30-50° from the axis in a loose one (about 0.45). Moving weight from
non-carrying to carrying directions (``--rules perp``: the weight of opened bi-hexagons in
extension to the direction across them that is compressed most) moves the fabric but not q/p;
turning the carrying ones does.

Parts (each written to the JSON, ``--parts``):

- ``split``: the stress of the REV at the package's defaults with the sand variant's mechanisms,
  α0 45° and 65°, drained at 100 kPa to 5 % and 25 %, by the cells' tilt (:func:`tilt_split`),
  the rule off and turning at the last κ of ``--kappas``;
- ``dem``: the same split of the DEM samples' stress by their contacts' tilt (:func:`dem_part`:
  two YADE tests, reused from ``--dem-folder`` when there);
- ``lateral``: why the REV's lateral bi-hexagons carry nothing (:func:`lateral_part`);
- ``fixed``: the sand variant's mechanisms at the package's default parameters, α0 45° and 65°,
  drained at 100 kPa (σ22 = σ33 = p0, one radial strain) to ``--strain``, steps of 1e-4, each
  rule of ``--rules`` (``off``, ``perp``, ``turn``) at each κ of ``--kappas``.
- ``orders``: the turning rule at the last κ of ``--kappas`` on spheres of Lebedev order 17 to 35
  (:func:`orders_part`).
- ``extension``: peak q/p in drained compression and extension at 100 kPa, α0 50° and 60°, the
  rule off and at the last κ of ``--kappas`` (:func:`extension_part`).
- ``kfs``: the Karlsruhe fine sand benchmark's calibration (``benchmarks/calibration/kfs.py``:
  TMD12 and TMD14, the same residuals, α0 at e_ref) of the sand variant redone by least squares
  from the record ``kfs_axisym_mix.json``'s optimum, with the rule off (G, ν, φg, α0) and on
  (κ as well), here on the generic driver (steps of 1e-3, the record's sphere); the 25 tests
  predicted (κ from each of :data:`KAPPA_STARTS`, the best kept); then the densest and loosest specimens at 100 and 400 kPa, drained and undrained,
  to 30 %, and drained on to 80 % (the void ratio e = e0 - εv (1 + e0) on the way);
- ``dem-judge``: the DEM judge of docs/mechanisms.md (record ``dem_judge_axisym_mix.json``) redone
  the same way, with the rule off and on (:func:`dem_judge_part`).

Usage: ``python -m benchmarks.model3d.fabric_turn [--parts split,dem,lateral,fixed,orders,extension,kfs,dem-judge] [--dem-folder DIR] [--out PATH]``. Prints
tables and writes ``fabric_turn.json``.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.model3d.critical_state import parse_mechanisms, segment
from benchmarks.model3d.carrying_census import SAND, carrying
from benchmarks.timing import ROOT, provenance
from hmodel import Params
from hmodel.cell import CellState
from hmodel.loading import NewtonSettings, Tangent, consolidate
from hmodel.loading.segment import GenericSegment
from hmodel.rev import Rev3D, Sphere
from hmodel.rev.rev3d import dyads, voigt_to_tensor
from hmodel.rev.state import RevState, deviatoric_stress, mean_stress, volumetric_strain
from hmodel.variants import get_variant

#: Fields of a bi-hexagon that hold forces (N1, N2, T1 of hexagons A and B).
FORCES = (3, 4, 5, 11, 12, 13)


def sand(alpha0: float) -> Params:
    """The package's default parameters with the sand variant's mechanisms (the census's), at the
    initial opening angle ``alpha0`` [deg]."""
    return Params(alpha0=math.radians(alpha0), **parse_mechanisms(SAND))


def turn(n: np.ndarray, w: np.ndarray, v: np.ndarray, deps: np.ndarray, carry: np.ndarray,
         kappa: float, delta: float) -> tuple[np.ndarray, np.ndarray, float]:
    """One application of the turning rule (the module's docstring): directions ``n`` (C, 3),
    weights ``w`` (C,), cells ``v`` (C, 16), the increment's strain tensor ``deps`` (3, 3),
    compression positive, the carrying cells ``carry`` (C,). Returns the new weights, cells and
    the weight moved."""
    w, v = w.copy(), v.copy()
    ev, vec = np.linalg.eigh(deps)
    rate = ev[-1] - ev[0]
    if kappa * rate <= 0.0:
        return w, v, 0.0
    # the major compression's eigenspace: one axis, or a plane where the two largest principal
    # increments are equal (triaxial extension); each cell turns towards its projection on it
    major = vec[:, ev >= ev[-1] - 1e-9 * rate]
    axes = (n @ major) @ major.T
    norms = np.linalg.norm(axes, axis=1)
    axes /= np.where(norms > 0.0, norms, 1.0)[:, None]
    cos = np.clip(np.einsum("ci,ci->c", n, axes), -1.0, 1.0)
    theta = np.where(norms > 0.0, np.arccos(cos), 0.5 * math.pi)
    moved = 0.0
    for c in np.argsort(-theta, kind="stable"):
        if not carry[c] or theta[c] <= 1e-12 or norms[c] <= 1e-12:
            continue
        axis = axes[c]
        side = n[c] - cos[c] * axis  # the part of n across the axis, in the plane of the two
        side /= np.linalg.norm(side)
        t = max(theta[c] - delta, 0.0)
        target = math.cos(t) * axis + math.sin(t) * side
        j = int(np.argmax(np.abs(n @ target)))
        if j == c:
            continue
        df = min(kappa * rate * math.sin(theta[c]) ** 2, 0.5) * w[c]
        total = w[j] + df
        v[j] = (w[j] * v[j] + df * v[c]) / total
        w[c] -= df
        w[j] = total
        moved += df
    return w, v, moved


def perp(n: np.ndarray, w: np.ndarray, v: np.ndarray, deps: np.ndarray, carry: np.ndarray,
         kappa: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The rule that moves the fabric but not q/p (the module's docstring): a bi-hexagon that
    carries nothing and whose axis is stretched by e_c < 0 gives κ w_c |e_c| of its weight to the
    direction across n_c that the increment compresses most; a receiving cell's forces are scaled
    by w_j / (w_j + Δw_j), the incoming weight being force-free, so Σ w (force) is unchanged."""
    w, v = w.copy(), v.copy()
    e = np.einsum("ci,ij,cj->c", n, deps, n)
    gain = np.zeros(len(w))
    loss = np.where(~carry & (e < 0.0), kappa * w * -e, 0.0)
    for c in np.flatnonzero(loss):
        across = np.eye(3) - np.outer(n[c], n[c])
        target = np.linalg.eigh(across @ deps @ across)[1][:, -1]
        gain[int(np.argmax(np.abs(n @ target)))] += loss[c]
    new = w - loss + gain
    scale = np.where(gain > 0.0, w / new, 1.0)
    v[:, FORCES] *= scale[:, None]
    return new, v, float(loss.sum())


def run(params: Params, p0: float, strain: float, step: float, rule: str = "off", kappa: float = 0.0,
        undrained: bool = False, sphere: Sphere | None = None, delta: float = math.radians(15.0),
        extension: bool = False) -> dict:
    """A drained (one radial strain, σ22 = σ33 = p0) or undrained triaxial test of one material
    point from isotropic consolidation at p0, in compression or (``extension``) with the axial
    strain reversed, the rule applied after every increment. Returns the curves from the start
    of shearing (ε11, p, q, εv, F11 = Σ w n1² / Σ w) and the weight moved."""
    rev = Rev3D([params], sphere or Sphere())
    n, w, dy = rev.frames[:, 0, :], rev.weights.copy(), dyads(rev.frames)
    p = np.array([p0])
    state = consolidate(rev, p)
    steps = round(strain / step)
    seg = segment(undrained, p, -strain if extension else strain, steps, "equal")
    runner = GenericSegment(rev, state, seg, state.sig @ np.asarray(seg.matrix, float).T,
                            np.asarray(seg.values, float), Tangent(), NewtonSettings())
    rows = [_row(state, n, w)]
    moved = 0.0
    for k in range(1, steps + 1):
        old = runner.state()
        runner.run(k, k + 1)
        new = runner.state()
        if rule != "off" and kappa > 0.0:
            v = new.cells.values[0]
            deps = voigt_to_tensor(new.eps[0] - old.eps[0])
            carry = carrying(v, w)
            if rule == "turn":
                w, v, dm = turn(n, w, v, deps, carry, kappa, delta)
            elif rule == "perp":
                w, v, dm = perp(n, w, v, deps, carry, kappa)
            else:
                raise ValueError(f"unknown rule {rule!r}")
            if dm > 0.0:
                moved += dm
                # the point's weights: the REV is this one point's (B = 1)
                rev.weights = w.copy()
                rev._wdyads = np.ascontiguousarray(w[:, None, None] * dy)
                rev.__dict__.pop("_kernel_inputs", None)  # renewal=mix reads the weights there
                cells = CellState(v[None])
                new = RevState(cells, new.flags, new.eps, rev.stress(cells, new.eps), new.sets)
                runner._state = new
        rows.append(_row(new, n, w))
    r = np.array(rows)
    r[:, 0] -= r[0, 0]
    r[:, 3] -= r[0, 3]
    return {"eps11": r[:, 0], "p": r[:, 1], "q": r[:, 2], "eps_v": r[:, 3], "F11": r[:, 4], "moved": moved,
            "rev": rev, "state": runner.state()}


def _row(state: RevState, n: np.ndarray, w: np.ndarray) -> tuple:
    return (state.eps[0, 0], float(mean_stress(state.sig)[0]), float(deviatoric_stress(state.sig)[0]),
            float(volumetric_strain(state.eps)[0]), float((w * n[:, 0] ** 2).sum() / w.sum()))


def at(path: dict, strain: float) -> dict:
    """q/p, εv and F11 of a path at the row nearest ``strain``."""
    i = int(np.argmin(np.abs(np.abs(path["eps11"]) - strain)))
    return {"eps11": float(path["eps11"][i]), "q_p": float(path["q"][i] / path["p"][i]),
            "eps_v": float(path["eps_v"][i]), "F11": float(path["F11"][i])}


#: Tilt bands [deg] of the stress splits (:func:`band_split`).
BANDS = ((0.0, 30.0), (30.0, 50.0), (50.0, 70.0), (70.0, 90.0))


def band_split(theta: np.ndarray, weight: np.ndarray, s11: np.ndarray, sr: np.ndarray) -> list[dict]:
    """Items (cells or contacts) of tilt ``theta`` [deg] from the compression axis, weight (a
    cell's w, or 1 a contact) and terms ``s11``, ``sr`` of σ11 and σr = (σ22 + σ33)/2, split by
    :data:`BANDS`: each band's share of the weight, of σ11 and of σr."""
    rows = []
    for lo, hi in BANDS:
        band = (theta >= lo) & ((theta < hi) if hi < 90.0 else (theta <= hi))
        rows.append({"theta": [lo, hi], "weight": float(weight[band].sum() / weight.sum()),
                     "sig11": float(s11[band].sum() / s11.sum()), "sig_r": float(sr[band].sum() / sr.sum())})
    return rows


def tilt_split(alpha0: float, strain: float, rule: str = "off", kappa: float = 0.0, p0: float = 100e3) -> dict:
    """The stress of the sand variant's REV (default parameters, α0 [deg]) at the end of a drained
    test to ``strain`` (steps of 1e-4, one radial strain, the rule as :func:`run`), split by the
    cells' tilt θ from the compression axis (:func:`band_split`; eq. 1.15 lifted, σ_tt the mean
    of the cell's two lateral components), with the REV's σ11/σr and the carrying cells' weighted
    σ_nn/σ_tt."""
    params = sand(alpha0)
    path = run(params, p0, strain, 1e-4, rule, kappa)
    rev, end = path["rev"], path["state"]
    vs, _ = rev.solver.meso(params, CellState(end.cells.values[0]))
    w, n1 = rev.weights, rev.frames[:, 0, 0]
    nn, tt = vs[:, 0], 0.5 * (vs[:, 1] + vs[:, 2])
    s11 = w * (nn * n1 ** 2 + tt * (1 - n1 ** 2))
    sr = w * (nn * (1 - n1 ** 2) / 2 + tt * (1 + n1 ** 2) / 2)
    carry = carrying(end.cells.values[0], w)
    return {"alpha0": alpha0, "eps11": strain, "rule": rule, "kappa": kappa, "q_p": at(path, strain)["q_p"],
            "sig11_over_sig_r": float(s11.sum() / sr.sum()), "F11": float(path["F11"][-1]),
            "carrying_nn_over_tt": float((w * nn)[carry].sum() / (w * tt)[carry].sum()),
            "bands": band_split(np.degrees(np.arccos(np.abs(n1))), w, s11, sr)}


def dem_split(folder: Path, name: str) -> dict:
    """The same split of a DEM sample's Love-Weber stress, (1/V) Σ f ⊗ l over its contacts, at
    the consolidated and the final state of its drained test at 100 kPa (``folder/name``, the
    npz of :func:`hmodel.dem.sample.run_sample`): contacts by the tilt of their branch vector,
    f = fn n + ft, the contacts that carry (fn > 0); with the contact fabric F11 = <n1²> and its
    normal-force-weighted twin Σ fn n1² / Σ fn."""
    data = np.load(folder / name / "triaxial-drained_100kPa.npz", allow_pickle=False)
    out = {"sample": name}
    for state in ("consolidated", "final"):
        c = data[f"{state}_contacts"]  # CONTACT_COLUMNS_3D: i, j, fn, ftx, fty, ftz, lx, ly, lz
        c = c[c[:, 2] > 0.0]
        fn, ft, lv = c[:, 2], c[:, 3:6], c[:, 6:9]
        n = lv / np.linalg.norm(lv, axis=1)[:, None]
        f = fn[:, None] * n + ft
        s11, sr = f[:, 0] * lv[:, 0], 0.5 * (f[:, 1] * lv[:, 1] + f[:, 2] * lv[:, 2])
        out[state] = {"contacts": int(len(c)), "sig11_over_sig_r": float(s11.sum() / sr.sum()),
                      "F11": float((n[:, 0] ** 2).mean()), "F11_force": float((fn * n[:, 0] ** 2).sum() / fn.sum()),
                      "bands": band_split(np.degrees(np.arccos(np.clip(np.abs(n[:, 0]), 0.0, 1.0))),
                                          np.ones(len(c)), s11, sr)}
    return out


def dem_part(folder: Path) -> list[dict]:
    """The granular benchmark's dense and loose Hertz-Mindlin samples of 600 spheres
    (``benchmarks/dem/granular.py``'s ``dense-hertz``, ``loose-hertz`` settings) drained at
    100 kPa to 25 %, run into ``folder`` (a test already there is reused), and their splits."""
    from benchmarks.dem.granular import parser, samples
    from hmodel.dem.sample import run_sample

    defined = samples(parser().parse_args([]))
    for name in ("dense-hertz", "loose-hertz"):
        run_sample(defined[name][1], [1e5], "triaxial-drained", folder / name)
    return [dem_split(folder, name) for name in ("dense-hertz", "loose-hertz")]


def _print_split(label: str, r: dict) -> None:
    print(f"{label}: σ11/σr {r['sig11_over_sig_r']:.3f}; " + "; ".join(
        f"θ {b['theta'][0]:g}-{b['theta'][1]:g}: weight {b['weight']:.3f}, σ11 {b['sig11']:.3f}, σr {b['sig_r']:.3f}"
        for b in r["bands"]))


def lateral_part(alpha0: float = 65.0, strain: float = 0.25, increments: int = 6) -> dict:
    """Why the REV's lateral bi-hexagons carry nothing: the loose REV (sand variant's mechanisms,
    defaults, α0 ``alpha0``) drained at 100 kPa to ``strain``, then its most lateral bi-hexagon
    (axis nearest 90° from the compression axis) stepped alone, ``increments`` times, by the
    REV's last strain increment (:func:`hmodel.rev.rev3d.Rev3D.localize` of it, the cell's own
    lengths each time): its forces, which contacts open, and its branch lengths against 2r;
    beside it, the weighted mean N1 of the cells that carry."""
    params = sand(alpha0)
    path = run(params, 100e3, strain, 1e-4, "off", 0.0)
    rev, end = path["rev"], path["state"]
    v = end.cells.values[0]
    c = int(np.argmin(np.abs(rev.frames[:, 0, 0])))
    d11 = float(path["eps11"][-1] - path["eps11"][-2])
    dr = 0.5 * (float(path["eps_v"][-1] - path["eps_v"][-2]) - d11)  # one radial strain: ε22 = ε33
    deps = np.array([[d11, dr, dr, 0.0, 0.0, 0.0]])
    two_r = 2.0 * params.radius
    cell = CellState(v[c:c + 1].copy())
    cells = end.cells.values.copy()  # (1, C, 16): the REV's localization needs all its cells' rows
    steps = []
    for _ in range(increments):
        cells[0, c] = cell.values[0]
        dl = rev.localize(CellState(cells), deps)[0, c:c + 1]
        cell, flags = rev.solver.step(params, cell, dl[:, 0], dl[:, 1], dl[:, 2])
        x, f = cell.values[0], flags.flags[0]
        steps.append({"N1": float(x[3]), "N2": float(x[4]), "open": [bool(f[k]) for k in (1, 2, 6, 7)],
                      "d1_minus_2r": float(x[0] - two_r), "d2_minus_2r": float(x[1] - two_r),
                      "alpha_deg": math.degrees(float(x[2]))})
    carry = carrying(v, rev.weights)
    out = {"alpha0": alpha0, "eps11": strain, "cell_axis": rev.frames[c, 0].tolist(),
           "alpha_start_deg": math.degrees(float(v[c, 2])), "deps_v_deps11": (2.0 * dr + d11) / d11,
           "carrying_mean_N1": float((rev.weights[carry] * v[carry, 3]).sum() / rev.weights[carry].sum()),
           "steps": steps}
    print(f"lateral bi-hexagon of the loose REV at {strain:.0%} (α {out['alpha_start_deg']:.2f}°, increments at "
          f"dεv/dε1 {out['deps_v_deps11']:+.4f}; the carrying cells' mean N1 {out['carrying_mean_N1']:.3g} N):")
    for k, st in enumerate(steps):
        print(f"   {k + 1}: N1 {st['N1']:8.2f} N2 {st['N2']:7.2f}  open (A1 A2 B1 B2) "
              f"{''.join(str(int(o)) for o in st['open'])}  d1-2r {st['d1_minus_2r']:+.2e}  d2-2r {st['d2_minus_2r']:+.2e}")
    return out


def orders_part(kappa: float, orders=(17, 23, 29, 35), delta: float = math.radians(15.0)) -> list[dict]:
    """The turning rule at κ ``kappa`` on spheres of several Lebedev orders (two azimuths): q/p at
    15 % and 30 % of the drained test at 100 kPa (α0 45° and 65°, steps of 1e-4), with each
    sphere's mean angle between a direction and its nearest neighbour (the rule turns a cell by
    ``delta`` to the nearest direction: a sphere coarser than that turns nothing)."""
    rows = []
    for order in orders:
        n = Sphere(order=order, n_azimuth=1).frames()[0][:, 0, :]
        cos = np.abs(n @ n.T)
        np.fill_diagonal(cos, 0.0)
        spacing = float(np.degrees(np.arccos(cos.max(axis=1))).mean())
        for a0 in (45.0, 65.0):
            params = sand(a0)
            path = run(params, 100e3, 0.3, 1e-4, "turn", kappa, sphere=Sphere(order=order, n_azimuth=2), delta=delta)
            rows.append({"order": order, "directions": len(n), "spacing_deg": spacing, "alpha0": a0,
                         "moved": path["moved"], "at": [at(path, s) for s in (0.15, 0.3)]})
            r = rows[-1]
            print(f"order {order} ({len(n)} directions, {spacing:.1f}° apart) α0 {a0:g}: q/p at 15 % "
                  f"{r['at'][0]['q_p']:.3f}, 30 % {r['at'][1]['q_p']:.3f}; F11 {r['at'][1]['F11']:.3f}")
    return rows


def extension_part(kappa: float, strain: float = 0.2, step: float = 1e-3) -> list[dict]:
    """Peak q/p in drained compression and extension (100 kPa, one radial strain, to ``strain``)
    of the sand variant's REV at the defaults, α0 50° and 60°, the rule off and turning at
    ``kappa``: the ratio of the peaks, M_e/M_c of the triaxial tests."""
    rows = []
    for rule, k in (("off", 0.0), ("turn", kappa)):
        for a0 in (50.0, 60.0):
            params = sand(a0)
            comp = run(params, 100e3, strain, step, rule, k)
            ext = run(params, 100e3, strain, step, rule, k, extension=True)
            rc, re = comp["q"] / comp["p"], -ext["q"] / ext["p"]  # q < 0 in extension
            rows.append({"rule": rule, "kappa": k, "alpha0": a0, "peak_compression": float(rc.max()),
                         "at_compression": float(comp["eps11"][rc.argmax()]), "peak_extension": float(re.max()),
                         "at_extension": float(ext["eps11"][re.argmax()]), "ratio": float(re.max() / rc.max()),
                         "F11_extension_end": float(ext["F11"][-1])})
            r = rows[-1]
            print(f"{rule:4s} κ {k:4g} α0 {a0:g}: peak q/p compression {r['peak_compression']:.3f} at "
                  f"{r['at_compression']:.3f}, extension {r['peak_extension']:.3f} at {r['at_extension']:.3f}, "
                  f"M_e/M_c {r['ratio']:.3f}; F11 at the extension's end {r['F11_extension_end']:.3f}")
    return rows


def fixed_part(rules: list[str], kappas: list[float], strain: float, marks: list[float]) -> list[dict]:
    rows = []
    for rule in rules:
        for kappa in ([0.0] if rule == "off" else kappas):
            for a0 in (45.0, 65.0):
                params = sand(a0)
                path = run(params, 100e3, strain, 1e-4, rule, kappa)
                rows.append({"rule": rule, "kappa": kappa, "alpha0": a0, "moved": path["moved"],
                             "at": [at(path, s) for s in marks]})
                print(f"{rule:5s} κ {kappa:4g} α0 {a0:g}: moved {path['moved']:.3f}  " + "  ".join(
                    f"{m['eps11']:.2f}: q/p {m['q_p']:.3f} εv {100 * m['eps_v']:+.1f}% F11 {m['F11']:.3f}"
                    for m in rows[-1]["at"]))
    return rows


#: Free parameters of the calibrations (the sand variant's fitted ones, then κ), their bounds and
#: scales: log10 G [Pa], ν, φg [deg], α0 at e_ref [deg], κ.
FREE = ("log10_shear_modulus", "poisson", "phi_g_deg", "alpha0_deg", "kappa")
LOWER, UPPER = np.array([7.0, 0.0, 5.0, 31.0, 0.0]), np.array([12.0, 0.45, 60.0, 69.1, 200.0])
SCALE = np.array([0.3, 0.05, 2.0, 2.0, 5.0])


def with_fitted(params: Params, x) -> Params:
    """``params`` with the calibrated values ``x`` (:data:`FREE`, κ aside)."""
    return replace(params, shear_modulus=10 ** x[0], poisson=x[1], phi_g=math.radians(x[2]), alpha0=math.radians(x[3]))


def specimen(model: tuple, x, e0: float) -> Params:
    """The parameters of a specimen at void ratio ``e0`` at the calibrated values ``x``;
    ``model`` = (variant, params, e_ref, sphere, step)."""
    variant, params, e_ref, _, _ = model
    return variant.initial_params(with_fitted(params, x), 3, e0, e_ref)


def start(params: Params) -> list[float]:
    """The calibration's start (:data:`FREE` without κ) at a record's optimum ``params`` (ν
    lifted from its bound 0 to 0.01, where least squares can move it)."""
    return [math.log10(params.shear_modulus), max(params.poisson, 0.01), math.degrees(params.phi_g),
            math.degrees(params.alpha0)]


def curves(test, x, rule: str, model: tuple) -> tuple[np.ndarray, np.ndarray]:
    """The model's q and εv at a test's axial strains (drained, undrained or extension, from its
    e0 and p0), at the calibrated values ``x``; ``model`` = (variant, params, e_ref, sphere, step).
    NaN where the model did not reach (its Newton failed), as the calibration benchmarks."""
    sphere, step = model[3:]
    kind = str(test.kind.value if hasattr(test.kind, "value") else test.kind)
    extension = kind.endswith("extension")
    sign = -1.0 if extension else 1.0
    nan = np.full(len(test.eps11), np.nan)
    try:
        path = run(specimen(model, x, test.e0), test.p0,
                   float(np.abs(test.eps11).max()), step, rule, x[4], undrained=kind.endswith("undrained"),
                   sphere=sphere, extension=extension)
    except Exception:
        return nan, nan.copy()
    e = sign * path["eps11"]
    q = np.interp(sign * test.eps11, e, path["q"])
    q[sign * test.eps11 > e[-1] + 1e-12] = np.nan
    return q, np.interp(sign * test.eps11, e, path["eps_v"])


def calibrate(cal: list, rule: str, k0: float, x0, max_nfev: int, model: tuple):
    """Least squares of :data:`FREE` (κ too with the rule on) on the tests ``cal``, with
    :func:`hmodel.calibrate.model.residuals`' scaling and weights (q over peak |q|, εv over its
    range where the test's kind observes it, each test over the root of its rows). Returns the
    values (κ = ``k0`` with the rule off) and scipy's result."""
    from scipy.optimize import least_squares

    from hmodel.calibrate.model import has_eps_v

    rows = sum(len(t.eps11) * (2 if has_eps_v(t) else 1) for t in cal)

    def residuals(y):
        x = np.r_[y, k0][:5]
        parts = []
        for t in cal:
            q, ev = curves(t, x, rule, model)
            if not np.all(np.isfinite(q)):
                return np.full(rows, 10.0)
            w = 1.0 / math.sqrt(len(t.eps11))
            parts.append(w * (q - t.q) / t.q_scale)
            if has_eps_v(t):
                parts.append(w * (ev - t.eps_v) / t.eps_v_scale)
        return np.concatenate(parts)

    free = 5 if rule == "turn" else 4
    sol = least_squares(residuals, np.r_[x0, k0][:free], bounds=(LOWER[:free], UPPER[:free]),
                        x_scale=SCALE[:free], diff_step=1e-3, max_nfev=max_nfev)
    return np.r_[sol.x, k0][:5], sol


#: The starts of κ of a calibration with the rule on (the objective has a flat valley in κ and
#: local minima: on the DEM judge a start at 5 stays near 5, at 0.197, where 20 and 60 reach
#: about 47, at 0.122); the best end is kept.
KAPPA_STARTS = (5.0, 20.0, 60.0)


def calibrate_best(cal: list, rule: str, x0, max_nfev: int, model: tuple):
    """:func:`calibrate` from each κ of :data:`KAPPA_STARTS` (one start with the rule off); the
    values and result of the lowest objective, and every start's κ, end κ and objective."""
    ends = [(k0, *calibrate(cal, rule, k0, x0, max_nfev, model)) for k0 in (KAPPA_STARTS if rule != "off" else (0.0,))]
    k0, x, sol = min(ends, key=lambda e: e[2].cost)
    return x, sol, [{"kappa_start": k, "kappa": float(xe[4]), "objective": float(se.cost)} for k, xe, se in ends]


def fitted_record(x, sol, starts: list) -> dict:
    return {"fitted": {"shear_modulus": 10 ** x[0], "poisson": x[1], "phi_g_deg": x[2], "alpha0_deg": x[3],
                       "kappa": x[4]}, "objective": float(sol.cost), "evaluations": int(sol.nfev), "starts": starts}


def kfs_part(max_nfev: int) -> dict:
    from benchmarks.calibration.kfs import CALIBRATION, errors, load_tests
    from benchmarks.calibration.kfs_long import stored

    variant, params, e_ref, sphere, step, _ = stored("axisym_mix")
    model = (variant, params, e_ref, sphere, step)
    tests = load_tests(1)[0]
    cal = [t for t in tests if t.name in CALIBRATION]
    x0 = start(params)
    out = {"record": "kfs_axisym_mix.json", "variant": variant.name, "e_ref": e_ref, "step": step,
           "sphere": {"order": sphere.order, "n_azimuth": sphere.n_azimuth}, "fits": {}}
    for rule in ("off", "turn"):
        x, sol, starts = calibrate_best(cal, rule, x0, max_nfev, model)
        rows = []
        for t in tests:
            q, ev = curves(t, x, rule, model)
            rows.append({"test": t.name, "e0": t.e0, "p0_kPa": t.p0 / 1e3, **errors(t, q, ev)})
        dq = [r["rms_dq"] for r in rows if r["rms_dq"] is not None]
        ends = []
        for e0 in (min(t.e0 for t in tests), max(t.e0 for t in tests)):
            for p0 in (100e3, 400e3):
                for undrained in (False, True):
                    try:
                        path = run(specimen(model, x, e0), p0, 0.3, step, rule, x[4], undrained=undrained,
                                   sphere=sphere)
                    except Exception as exc:
                        ends.append({"e0": e0, "p0_kPa": p0 / 1e3, "undrained": undrained,
                                     "failed": str(exc).split(":")[0]})
                        continue
                    last = path["eps11"] >= 0.25
                    ends.append({"e0": e0, "p0_kPa": p0 / 1e3, "undrained": undrained, **at(path, 0.3),
                                 "q_p_25": at(path, 0.25)["q_p"], "p_end_kPa": float(path["p"][-1] / 1e3),
                                 "p_min_kPa": float(path["p"].min() / 1e3),
                                 "deps_v_deps11_end": float(np.polyfit(path["eps11"][last], path["eps_v"][last], 1)[0])})
        long = []  # the drained tests of the densest and loosest specimens on to 80 %
        for e0 in (min(t.e0 for t in tests), max(t.e0 for t in tests)):
            for p0 in (100e3, 400e3):
                path = run(specimen(model, x, e0), p0, 0.8, step, rule, x[4], sphere=sphere)
                last = path["eps11"] >= 0.7
                marks = [at(path, s) for s in (0.3, 0.5, 0.8)]
                long.append({"e0": e0, "p0_kPa": p0 / 1e3, "at": marks,
                             # e = e0 - εv (1 + e0), εv contraction positive (benchmarks.calibration.kfs.sand_ends)
                             "e": [e0 - m["eps_v"] * (1 + e0) for m in marks], "p_end_kPa": float(path["p"][-1] / 1e3),
                             "deps_v_deps11_end": float(np.polyfit(path["eps11"][last], path["eps_v"][last], 1)[0])})
        out["fits"][rule] = {
            **fitted_record(x, sol, starts),
            "median_rms_dq": float(np.median(dq)), "within_10": int(sum(d <= 0.10 for d in dq)),
            "max_rms_dq": float(max(dq)),
            "median_rms_dev": float(np.median([r["rms_dev"] for r in rows if r["rms_dev"] is not None])),
            "within_both": int(sum((r["rms_dq"] is not None and r["rms_dq"] <= 0.10 and r["rms_dev"] <= 0.005)
                                   for r in rows)),
            "tests": rows, "ends": ends, "long": long}
        f = out["fits"][rule]
        print(f"KFS {rule}: fitted {', '.join(f'{k} {v:.4g}' for k, v in f['fitted'].items())}; objective "
              f"{f['objective']:.5f}; median RMS |Δq|/peak q {100 * f['median_rms_dq']:.1f} %, "
              f"{f['within_10']} of 25 within 10 %, {f['within_both']} within both")
        for e in ends:
            kind = "undrained" if e["undrained"] else "drained"
            print(f"   e0 {e['e0']:.3f} {e['p0_kPa']:.0f} kPa {kind:9s}: " + (
                f"Newton failed ({e['failed']})" if "failed" in e else
                f"q/p 25 % {e['q_p_25']:.3f}, 30 % {e['q_p']:.3f}; p min {e['p_min_kPa']:.0f}, end "
                f"{e['p_end_kPa']:.0f} kPa; εv {100 * e['eps_v']:+.2f} %; dεv/dε1 {e['deps_v_deps11_end']:+.3f}; "
                f"F11 {e['F11']:.3f}"))
        for e in long:
            print(f"   e0 {e['e0']:.3f} {e['p0_kPa']:.0f} kPa drained to 80 %: q/p "
                  + " / ".join(f"{m['q_p']:.3f}" for m in e["at"]) + " at 30 / 50 / 80 %; e "
                  + " / ".join(f"{v:.3f}" for v in e["e"]) + f"; dεv/dε1 at the end {e['deps_v_deps11_end']:+.3f}")
    return out


def dem_judge_part(max_nfev: int) -> dict:
    """The DEM judge of docs/mechanisms.md redone in the probe: the sand variant calibrated as its
    record ``dem_judge_axisym_mix.json`` was (the dense Hertz-Mindlin sample's drained test at
    100 kPa and the loose one's at 400 kPa, each test from the e0 of its CSV, the record's e_ref,
    sphere and step), from the record's optimum, with the rule off and on; every other test of
    the two samples predicted (drained, undrained, extension)."""
    from benchmarks.calibration.calibrate3d_dem import errors, read_tests

    rec = json.loads((ROOT / "benchmarks" / "calibration" / "dem_judge_axisym_mix.json").read_text())
    m = rec["calibration"]["model"]
    variant = get_variant(m["variant"])
    params = Params(**m["params_rad"])
    sphere = Sphere(order=rec["calibration"]["sphere"]["order"], n_azimuth=rec["calibration"]["sphere"]["n_azimuth"])
    model = (variant, params, m["e_ref"], sphere, m["step"])
    tests = {}
    for folder in rec["options"]["sample"]:
        tests |= read_tests(ROOT / folder, Path(folder).name + "/")
    fit_on = rec["options"]["fit_on"].split(",")
    x0 = start(params)
    out = {"record": "dem_judge_axisym_mix.json", "variant": variant.name, "fit_on": fit_on, "fits": {}}
    for rule in ("off", "turn"):
        x, sol, starts = calibrate_best([tests[n] for n in fit_on], rule, x0, max_nfev, model)
        rows = {}
        for name, t in tests.items():
            q, ev = curves(t, x, rule, model)
            ok = np.all(np.isfinite(q))
            rows[name] = {"how": "calibrated on" if name in fit_on else "predicted",
                          **({"rms_dq": float(errors(t, q, ev)["rms_dq"])} if ok else {"rms_dq": None, "failed": True})}
        out["fits"][rule] = {**fitted_record(x, sol, starts), "tests": rows}
        f = out["fits"][rule]
        print(f"DEM judge {rule}: fitted {', '.join(f'{k} {v:.4g}' for k, v in f['fitted'].items())}; objective "
              f"{f['objective']:.5f}")
        for n, r in rows.items():
            print(f"   {n} ({r['how']}): " + ("failed" if r["rms_dq"] is None else f"{100 * r['rms_dq']:.1f} %"))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default="split,dem,lateral,fixed,orders,extension,kfs,dem-judge")
    ap.add_argument("--dem-folder", type=Path, default=Path("results/fabric-dem"),
                    help="where the DEM part runs its two tests (reused when there)")
    ap.add_argument("--rules", default="off,perp,turn")
    ap.add_argument("--kappas", default="5,20")
    ap.add_argument("--strain", type=float, default=0.5)
    ap.add_argument("--marks", default="0.05,0.15,0.3,0.5", help="strains the fixed part reports")
    ap.add_argument("--max-nfev", type=int, default=60, help="evaluations of each KFS fit")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("fabric_turn.json"))
    args = ap.parse_args()
    parts = args.parts.split(",")
    result = {**provenance(__file__, args)}
    if "split" in parts:
        kappa = float(args.kappas.split(",")[-1])
        result["split"] = [tilt_split(a0, e, rule, k) for rule, k in (("off", 0.0), ("turn", kappa))
                           for a0 in (45.0, 65.0) for e in (0.05, 0.25)]
        for r in result["split"]:
            _print_split(f"REV α0 {r['alpha0']:g} ε1 {r['eps11']:g} {r['rule']} κ {r['kappa']:g} (q/p {r['q_p']:.3f}, "
                         f"F11 {r['F11']:.3f}, carrying σnn/σtt {r['carrying_nn_over_tt']:.2f})", r)
    if "dem" in parts:
        result["dem"] = dem_part(args.dem_folder)
        for r in result["dem"]:
            for state in ("consolidated", "final"):
                x = r[state]
                _print_split(f"DEM {r['sample']} {state} ({x['contacts']} contacts, F11 {x['F11']:.3f}, "
                             f"force-weighted {x['F11_force']:.3f})", x)
    if "fixed" in parts:
        result["fixed"] = fixed_part(args.rules.split(","), [float(k) for k in args.kappas.split(",")],
                                     args.strain, [float(s) for s in args.marks.split(",")])
    if "lateral" in parts:
        result["lateral"] = lateral_part()
    if "orders" in parts:
        result["orders"] = orders_part(float(args.kappas.split(",")[-1]))
    if "extension" in parts:
        result["extension"] = extension_part(float(args.kappas.split(",")[-1]))
    if "kfs" in parts:
        result["kfs"] = kfs_part(args.max_nfev)
    if "dem-judge" in parts:
        result["dem_judge"] = dem_judge_part(args.max_nfev)
    args.out.write_text(json.dumps(result, indent=2, default=float) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
