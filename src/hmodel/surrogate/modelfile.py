"""Surrogate model files: safetensors weights plus JSON metadata, loaded without unpickling.

One ``.safetensors`` file holds the layer weights and biases, the scaler offsets and scales
(float64), and under the header key ``hmodel`` a JSON document: format version, formulation,
architecture, normalization, material parameters, the training dataset's checksum, the training
configuration and history summary, metrics and the package version. A SHA-256 over the tensors
and that JSON (stored as ``checksum``) detects any alteration; a truncated file fails to parse.
Either way, and for a file of another format version, loading is refused with a clear message.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import HModelError
from .formulations import formulation_from_dict
from .model import Architecture, Surrogate
from .scalers import Affine

FORMAT = "hmodel-surrogate"
FORMAT_VERSION = 1


class ModelFileError(HModelError):
    """A model file that is missing, truncated, altered or of another format version."""


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
    save_file(tensors, str(tmp), metadata=header)
    os.chmod(tmp, 0o644)  # a model file is data anyone may read
    os.replace(tmp, path)
    return path


def load(path: "str | os.PathLike") -> Surrogate:
    """Read a model file; refuse anything truncated, altered or of another format version."""
    from safetensors import SafetensorError
    from safetensors.numpy import load_file
    from safetensors import safe_open

    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"model file {str(path)!r} does not exist")
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
    f, a = meta["formulation"], meta["architecture"]
    form = formulation_from_dict(f)
    arch = Architecture(a["width"], a["depth"], a["activation"])
    weights = [(tensors[f"layer{i}.weight"], tensors[f"layer{i}.bias"]) for i in range(a["n_layers"])]
    method = meta["normalization"]
    return Surrogate(form, arch, Affine(method, tensors["x_offset"], tensors["x_scale"]),
                     Affine(method, tensors["y_offset"], tensors["y_scale"]), weights, meta,
                     tensors.get("input_range"))
