"""What every YADE scene of hmodel shares (YADE side, see :mod:`hmodel.dem.yade.scripts`)."""


def stiffness(w, kn, kt_kn):
    """The contact physics: kn and ks = kt_kn kn for every pair (``w`` is ``yade.wrapper``).

    MatchMakers, because YADE's default, the harmonic mean 2 E Ra Rb / (Ra + Rb), gives kn = E r
    only for equal radii r, while the H-model's kn is a contact constant.
    """
    return w.Ip2_FrictMat_FrictMat_FrictPhys(kn=w.MatchMaker(algo="val", val=kn),
                                             ks=w.MatchMaker(algo="val", val=kt_kn * kn))


def steps(O, n):
    """n time steps (O.step() in a loop: O.run(n, True) adds a fixed wait to every call,
    longer than the few steps a balanced cell needs)."""
    for _ in range(n):
        O.step()
