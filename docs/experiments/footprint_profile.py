#!/usr/bin/env python3
"""Issue 46 item 6 (session 37): a beam's residual on a sphere against its miss distance.

A VLP-16 beam (1-sigma half-angles 0.75 / 0.375 mrad: the manual's 3.0 / 1.5 mrad full
divergence as 4 sigma) at 30 m on a 0.25 m sphere. The return's range is the energy-weighted
(w cos(incidence)) mean over the sub-rays that hit, placed on the beam's axis; the residual
is its distance from the centre less the radius. Printed against k, the axis's distance from
the limb in footprint sigmas (along or across the scan): the simulator's five rays (main), its
81-ray grid (the patch: 0.5 sigma apart within 2.5 sigma) and a 161 x 161 rendering of the
continuous Gaussian.
"""
import numpy as np

R, r, SA, SC = 30.0, 0.25, 0.75e-3, 0.375e-3


FIVE = [(0.0, 0.0, 0.4), (1.8257, 0.0, 0.15), (-1.8257, 0.0, 0.15), (0.0, 1.8257, 0.15),
        (0.0, -1.8257, 0.15)]


def residual(ma, mc, fine=False, step=0.5, reach=5, five=False):
    """The residual [m] for the centre at (ma, mc) across the axis, None when nothing hits."""
    c = np.array([ma, mc, R])
    if five:
        a, b = np.array([x[0] for x in FIVE]), np.array([x[1] for x in FIVE])
    elif fine:
        g = np.linspace(-4, 4, 161)
        a, b = np.meshgrid(g, g)
        a, b = a.ravel(), b.ravel()
    else:
        ij = [(i, j) for i in range(-reach, reach + 1) for j in range(-reach, reach + 1)
              if i * i + j * j <= reach * reach]
        a = np.array([i * step for i, _ in ij])
        b = np.array([j * step for _, j in ij])
    w = np.array([x[2] for x in FIVE]) if five else np.exp(-(a * a + b * b) / 2)
    w /= w.sum()
    d = np.stack([a * SA, b * SC, np.ones_like(a)], 1)
    d /= np.linalg.norm(d, axis=1)[:, None]
    p = d @ c
    disc = p * p - (c @ c - r * r)
    hit = disc > 0
    if not hit.any():
        return None
    t = p[hit] - np.sqrt(disc[hit])
    x = d[hit] * t[:, None]
    cos = np.abs(np.sum((x - c) / r * d[hit], 1))
    e = w[hit] * cos
    rng = (e * t).sum() / e.sum()
    return np.linalg.norm(np.array([0.0, 0.0, rng]) - c) - r


def mm(x):
    return "   none" if x is None else f"{x * 1e3:7.2f}"


print("    k   along: five    grid    fine | across: five    grid    fine  [mm]")
for k in np.arange(-3, 3.01, 0.25):
    al = [residual(r + k * SA * R, 0.0, f, five=v) for f, v in ((0, 1), (0, 0), (1, 0))]
    ac = [residual(0.0, r + k * SC * R, f, five=v) for f, v in ((0, 1), (0, 0), (1, 0))]
    print(f"{k:+.2f}        " + " ".join(map(mm, al)) + " |        " + " ".join(map(mm, ac)))
