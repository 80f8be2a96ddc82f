"""Surrogate model files: safetensors weights plus JSON metadata, loaded without unpickling.

One ``.safetensors`` file holds the layer weights and biases, the scaler offsets and scales
(float64), optionally a trust reference (:mod:`hmodel.surrogate.trust`), and under the header key ``hmodel`` a JSON document: format version, formulation,
architecture, normalization, material parameters, the training dataset's checksum, the training
configuration and history summary, metrics and the package version. A SHA-256 over the tensors
and that JSON (stored as ``checksum``) detects any alteration; a truncated file fails to parse.
Either way, and for a file of another format version, loading is refused with a clear message.
The checksum is no signature: anyone can recompute it, so a file whose metadata disagree with its
tensors (another number of layers, other sizes) or name an unknown formulation is refused too.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import InputError
from .formulations.registry import FORMULATIONS, formulation_from_dict
from .model import Architecture, Surrogate
from .scalers import METHODS, Affine

FORMAT = "hmodel-surrogate"
FORMAT_VERSION = 1


class ModelFileError(InputError):
    """A model file that is missing, truncated, altered, inconsistent or of another format version."""


def _digest(tensors: dict[str, np.ndarray], meta_json: str) -> str:
    h = hashlib.sha256()
    for k in sorted(tensors):
        a = np.ascontiguousarray(tensors[k])
        h.update(k.encode())
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    h.update(meta_json.encode())
    return h.hexdigest()


def _tensors(s: Surrogate) -> dict[str, np.ndarray]:
    t = {"x_offset": s.x_scaler.offset, "x_scale": s.x_scaler.scale,
         "y_offset": s.y_scaler.offset, "y_scale": s.y_scaler.scale}
    for i, (W, b) in enumerate(s.weights):
        t[f"layer{i}.weight"], t[f"layer{i}.bias"] = W, b
    if s.input_range is not None:
        t["input_range"] = s.input_range
    if s.trust_reference is not None:
        t["trust_reference"] = s.trust_reference
    return {k: np.ascontiguousarray(v, dtype=np.float64) for k, v in t.items()}


def save(s: Surrogate, path: "str | os.PathLike") -> Path:
    """Write ``s`` atomically to ``path`` (``.safetensors``)."""
    from safetensors.numpy import save_file

    path = Path(path)
    f = s.formulation
    # the model's own description last: metadata carried over from another model (a loaded
    # file's, a teacher's) never overrides it
    meta = {**s.meta, "format": FORMAT, "format_version": FORMAT_VERSION, "hmodel": __version__,
            "formulation": f.to_dict(),
            "architecture": {"width": s.architecture.width, "depth": s.architecture.depth,
                             "activation": s.architecture.activation, "n_layers": len(s.weights)},
            "normalization": s.x_scaler.method}
    meta_json = json.dumps(meta, sort_keys=True)
    tensors = _tensors(s)
    header = {"hmodel": meta_json, "checksum": _digest(tensors, meta_json)}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    try:
        save_file(tensors, str(tmp), metadata=header)
        os.chmod(tmp, 0o644)  # a model file is data anyone may read
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise InputError(f"cannot write model file {str(path)!r}: {e.strerror or e}") from None
    except BaseException:  # an interrupted or failed write leaves no .part behind
        tmp.unlink(missing_ok=True)
        raise
    return path


def load(path: "str | os.PathLike") -> Surrogate:
    """Read a model file; refuse anything truncated, altered, inconsistent or of another format
    version (:class:`ModelFileError`, an :class:`~hmodel.errors.InputError`)."""
    from safetensors import SafetensorError
    from safetensors.numpy import load_file
    from safetensors import safe_open

    path = Path(path)
    if not path.is_file():  # a device such as /dev/zero is never read: it has no end
        what = ("is a folder" if path.is_dir() else "is not a regular file" if path.exists()
                else "does not exist")
        raise ModelFileError(f"model file {str(path)!r} {what}")
    try:
        with safe_open(str(path), framework="np") as fh:
            header = fh.metadata() or {}
        tensors = load_file(str(path))
    except (SafetensorError, OSError, ValueError, UnicodeDecodeError) as e:
        raise ModelFileError(f"{str(path)!r} is not a readable model file (truncated or not "
                             f"safetensors): {' '.join(str(e).split())[:120]}") from None
    meta_json = header.get("hmodel")
    if meta_json is None or "checksum" not in header:
        raise ModelFileError(f"{str(path)!r} is a safetensors file but not an hmodel surrogate")
    if _digest(tensors, meta_json) != header["checksum"]:
        raise ModelFileError(f"{str(path)!r} does not match its checksum (the file was altered)")
    meta = json.loads(meta_json)
    if meta.get("format") != FORMAT or meta.get("format_version") != FORMAT_VERSION:
        raise ModelFileError(f"{str(path)!r} has format version {meta.get('format_version')}; "
                             f"this hmodel ({__version__}) reads version {FORMAT_VERSION}")
    try:
        return _surrogate(meta, tensors)
    except InputError as e:
        raise ModelFileError(f"{str(path)!r} is inconsistent: {e}") from None
    except (KeyError, TypeError, ValueError) as e:
        raise ModelFileError(f"{str(path)!r} has incomplete metadata ({type(e).__name__}: "
                             f"{' '.join(str(e).split())[:120]})") from None


def _surrogate(meta: dict, tensors: dict[str, np.ndarray]) -> Surrogate:
    """The model a file's metadata and tensors describe; InputError naming the first thing in
    which they disagree (the formulation, the layers, a tensor's shape)."""
    f, a = meta["formulation"], meta["architecture"]
    name = f.get("name") if isinstance(f, dict) else f
    if name not in FORMULATIONS:
        raise InputError(f"unknown formulation {name!r} (known: {', '.join(FORMULATIONS)})")
    if meta["normalization"] not in METHODS:
        raise InputError(f"unknown normalization {meta['normalization']!r} (known: {', '.join(METHODS)})")
    n = a["n_layers"]
    held = {k.split(".")[0] for k in tensors if k.startswith("layer")}
    want = ({f"layer{i}.{part}" for i in range(n) for part in ("weight", "bias")}
            if isinstance(n, int) and not isinstance(n, bool) else set())
    if not want or want != {k for k in tensors if k.startswith("layer")}:
        raise InputError(f"the metadata name {n!r} layers, the tensors hold {len(held)}")
    extra = set(tensors) - want - {"x_offset", "x_scale", "y_offset", "y_scale", "input_range",
                                   "trust_reference"}
    if extra:
        raise InputError(f"unexpected tensors {', '.join(sorted(extra))}")
    if a["depth"] != n - 1:
        raise InputError(f"the metadata give depth {a['depth']!r} for {n} layers (depth + 1 expected)")
    x, y = tensors["x_offset"], tensors["y_offset"]
    if x.ndim != 1 or y.ndim != 1 or (tensors["x_scale"].shape, tensors["y_scale"].shape) != (x.shape, y.shape):
        raise InputError("the scalers' offsets and scales differ in shape")
    weights = [(tensors[f"layer{i}.weight"], tensors[f"layer{i}.bias"]) for i in range(n)]
    size = len(x)
    for i, (W, b) in enumerate(weights):
        out = a["width"] if i < n - 1 else len(y)
        if W.shape != (out, size) or b.shape != (out,):
            raise InputError(f"layer {i} has weights {W.shape} and bias {b.shape}; the metadata and "
                             f"scalers give ({out}, {size}) and ({out},)")
        size = out
    rng = tensors.get("input_range")
    if rng is not None and rng.shape != (2, len(x)):
        raise InputError(f"the input range has shape {rng.shape} for {len(x)} inputs")
    trust = tensors.get("trust_reference")
    if trust is not None and (trust.ndim != 2 or trust.shape[1] != len(x) or "trust" not in meta):
        raise InputError(f"the trust reference has shape {trust.shape} for {len(x)} inputs"
                         + ("" if "trust" in meta else " and no trust metadata"))
    method = meta["normalization"]
    form = formulation_from_dict(f)
    if form.material_inputs and not meta.get("domain"):
        raise InputError(f"a network over a range of materials (inputs {', '.join(form.material_inputs)}) "
                         f"needs its training domain, and the metadata hold none")
    return Surrogate(form, Architecture(a["width"], a["depth"], a["activation"]),
                     Affine(method, tensors["x_offset"], tensors["x_scale"]),
                     Affine(method, tensors["y_offset"], tensors["y_scale"]), weights, meta, rng, trust)
