"""PyTorch, the one optional dependency of training (``pip install 'hmodel[train]'``).

Inference is NumPy: loading a model, :class:`~hmodel.surrogate.solver.SurrogateSolver`,
``hmodel run | compare | reproduce --quick`` never import torch. Every training or distillation
path reaches torch through :func:`require_torch`, which turns its absence into one
:class:`~hmodel.errors.InputError` naming the extra (the CLI prints it as one line, exit 1).
"""

from __future__ import annotations

from ..errors import InputError

EXTRA = "hmodel[train]"


def require_torch(purpose: str = "training"):
    """The ``torch`` module; without PyTorch installed, an InputError naming the extra.

    >>> try:
    ...     torch = require_torch()
    ... except InputError as e:
    ...     assert "pip install 'hmodel[train]'" in str(e)
    """
    try:
        import torch
    except ImportError:
        raise InputError(f"{purpose} needs PyTorch: pip install '{EXTRA}'") from None
    return torch
