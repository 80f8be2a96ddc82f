"""Regularizations as classes: a new variant plugs into the boundary-value problems as one class
(here one defined in this file and never registered: its problem, check and warning are the
ones the run uses), and the built-in variants' specs read back as themselves."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import pytest

from hmodel import Params
from hmodel.errors import InputError
from hmodel.fem import biaxial
from hmodel.fem.newton import Problem
from hmodel.fem.regularization import VARIANTS, Local, Nonlocal, Regularization

PARAMS = Params(n_theta=12, sliding_rhs="equilibrium")
RUN = {"mesh": (1, 2), "n_steps": 2, "reference": False}


@dataclass(frozen=True)
class Capped(Regularization):
    """The local model on specimens no wider than ``width`` [m], with a note: the whole of a new
    variant."""

    width: float
    built: list = field(default_factory=list, compare=False)  # its problems: the run used it
    name: ClassVar[str] = "capped"
    usage: ClassVar[str] = "capped:WIDTH"

    def __str__(self) -> str:
        return f"capped:{self.width:g}"

    def problem(self, basis, material, fixed, g, f_ext, b_bar) -> Problem:
        pb = Problem(basis, material, fixed, g, f_ext, b_bar)
        self.built.append(pb)
        return pb

    def check(self, domain) -> None:
        if domain.width > self.width:
            raise InputError(f"capped at {self.width:g} m, the specimen is {domain.width:g} m wide")

    def warning(self, domain) -> str | None:
        return f"capped at {self.width:g} m"


def test_a_variant_defined_outside_the_package_is_one_class_the_run_uses():
    reg = Capped(0.05)
    res = biaxial(PARAMS, 2e5, 0.002, regularization=reg, **RUN)
    assert len(reg.built) == 1 and type(reg.built[0]) is Problem
    assert res.meta["regularization"] == "capped:0.05" and res.meta["warnings"] == ["capped at 0.05 m"]
    local = biaxial(PARAMS, 2e5, 0.002, regularization="local", **RUN)
    for c in ("sig11", "sig22", "q", "eps_v"):
        np.testing.assert_array_equal(res.rows[c], local.rows[c])  # its problem is the local one
    narrow = Capped(0.01)
    with pytest.raises(InputError, match=r"^capped at 0.01 m, the specimen is 0.05 m wide$"):
        biaxial(PARAMS, 2e5, 0.002, regularization=narrow, **RUN)
    assert narrow.built == []  # refused before any problem was built


def test_a_variant_is_named_by_a_spec_only_when_listed():
    assert Capped not in VARIANTS
    with pytest.raises(InputError, match=r"^unknown regularization 'capped:0.05' \(known: local, "
                                         r"nonlocal:ell=LENGTH\)$"):
        Regularization.from_spec("capped:0.05")


@pytest.mark.parametrize("reg", [Local(), Nonlocal(0.005), Nonlocal(0.002, 0.2)])
def test_the_built_in_variants_read_back_from_their_specs(reg):
    again = Regularization.from_spec(str(reg))
    assert again == reg and type(again) is type(reg) and again.kind == reg.name
    assert Regularization.from_spec(reg) is reg
