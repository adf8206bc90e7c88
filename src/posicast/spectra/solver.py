"""The root finder's bookkeeping: the roots found so far, their multiplicities, reconciliation.

:class:`Solver` holds the distinct roots found in a rectangle (:class:`FoundRoot`).
Newton's converged points are merged into them (:meth:`Solver.absorb`); every new root
gets its multiplicity (:meth:`Solver.classify`, step 3 of :func:`posicast.roots`); when
the roots found do not add up to the certified count the rectangle is split, each part
counted and searched on a finer grid, recursively (:meth:`Solver.reconcile`, step 4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .argument_principle import OnBoundary, count_in_rect
from .candidates import grid_candidates, newton
from .checks import RootFindingError
from .disks import PelletDisk, cluster_rho_max, pellet
from .evaluation import Evaluator, relative_residual, scaled_eval

__all__ = ["FoundRoot", "Cluster", "Solver", "inside"]


@dataclass
class FoundRoot:
    """A distinct root found: ``mult`` 0 until classified, -1 once merged into a cluster (dropped)."""

    point: complex
    mult: int
    radius: float = 0.0  # a Pellet disk |s - centre| < radius certified to hold exactly ``mult`` roots
    centre: complex = 0j


def inside(z: np.ndarray, rect: tuple[float, float, float, float]) -> np.ndarray:
    """Which points of ``z`` lie in the closed rectangle ``rect``."""
    a, b, c, d = rect
    return (z.real >= a) & (z.real <= b) & (z.imag >= c) & (z.imag <= d)


class Cluster(NamedTuple):
    """A cluster of roots (a multiple root split by rounding) certified by a Pellet disk about ``centre``."""

    centre: complex
    disk: PelletDisk


@dataclass
class _Suspects:
    """New roots where ``|h'|`` is not well above its rounding scale: members of root clusters.

    Arrays, not lists searched per suspect: a search can hold thousands of clusters.
    """

    roots: list[FoundRoot]
    points: np.ndarray
    alive: np.ndarray  # not yet taken into a cluster

    @classmethod
    def of(cls, roots: list[FoundRoot]) -> "_Suspects":
        points = np.array([g.point for g in roots])
        return cls(roots, points, np.ones(points.size, dtype=bool))

    def take_group(self, i: int, rc: float) -> list[FoundRoot]:
        """Suspect ``i`` and every suspect left within ``2 rc`` of it, taken out."""
        f = self.roots[i]
        self.alive[i] = False
        idx = np.flatnonzero(self.alive & (np.abs(self.points - f.point) <= 2 * rc))
        self.alive[idx] = False
        return [f] + [self.roots[j] for j in idx]

    def drop_inside(self, centre: complex, radius: float) -> None:
        """Suspects inside an isolation disk are among its roots: one cluster, counted once."""
        inside = np.flatnonzero(self.alive & (np.abs(self.points - centre) < radius))
        for j in inside:
            self.roots[j].mult = -1
        self.alive[inside] = False


@dataclass
class _KnownRoots:
    """The roots already counted (multiplicity >= 1), as arrays."""

    roots: list[FoundRoot]
    points: np.ndarray
    simple: np.ndarray
    alive: np.ndarray  # not yet taken back into a cluster

    @classmethod
    def of(cls, found: list[FoundRoot]) -> "_KnownRoots":
        known = [g for g in found if g.mult >= 1]
        points = np.array([g.point for g in known], dtype=complex)
        simple = np.array([g.mult == 1 for g in known], dtype=bool)
        return cls(known, points, simple, np.ones(points.size, dtype=bool))

    def take_back(self, idx: np.ndarray) -> None:
        """Roots taken for simple ones that belong to a cluster: replaced by the cluster."""
        for j in idx:
            self.roots[j].mult = -1
        self.alive[idx] = False


_MAX_SIDE = 128  # grid nodes a side of a reconciliation search


class Solver:
    """The distinct roots found in ``rect`` so far, and how they are found, classified and reconciled."""

    def __init__(self, ev: Evaluator, rect: tuple[float, float, float, float], step: float) -> None:
        self.ev = ev
        self.rect = rect
        self.step = step
        self.found: list[FoundRoot] = []
        # a root of h has multiplicity at most sum_k (deg p_k + 1) - 1 (Polya-Szego bound)
        self.max_cluster = min(40, int(ev.q.coeffs.size))
        # roots of a chain are about 2 pi / tau apart (see grid_step); a polynomial has no such scale
        self.delay_step = math.pi / (3.0 * ev.tau_max) if ev.tau_max > 0 else math.inf

    def absorb(self, pts: np.ndarray) -> None:
        """Merge newly converged points into the list of distinct roots (new ones with ``mult`` 0)."""
        pts = pts[inside(pts, self.rect)]
        if pts.size == 0:
            return
        q = self.ev.q
        # An exact root at s = 0 of an h whose every term vanishes there (a loop with an
        # integrator and a distributed shaper) is reached as z ~ 1e-32, where |h| and the
        # term scale are both rounding: snap it onto 0, where the residual is exact.
        if q(0.0) == 0:
            pts = np.where(np.abs(pts) <= 1e-13, 0.0 + 0.0j, pts)
        pts = pts[relative_residual(q, pts) <= 1e-6]
        # cluster: points closer than tol are one root (or one cluster of roots)
        order = np.argsort(pts.real + 1e-3 * pts.imag)
        pts = pts[order]
        if pts.size == 0:
            return
        # vectorised against the roots already found (a search can hold thousands)
        known = np.array([f.point for f in self.found], dtype=complex)
        centres = np.array([f.centre for f in self.found], dtype=complex)
        radii = np.array([f.radius for f in self.found])
        tol_known = 1e-7 * np.maximum(1.0, np.abs(known))
        new = np.empty(pts.size, dtype=complex)
        n_new = 0
        for p in pts:
            tol = 1e-7 * max(1.0, abs(p))
            # a point inside a cluster's certified disk is one of the roots already counted there
            # (Newton stalls about sqrt(eps) away from a double root, farther than tol)
            if known.size and np.any((np.abs(p - known) <= np.maximum(tol, tol_known)) | (np.abs(p - centres) < radii)):
                continue
            if n_new and np.any(np.abs(p - new[:n_new]) <= np.maximum(tol, 1e-7 * np.maximum(1.0, np.abs(new[:n_new])))):
                continue
            new[n_new] = p
            n_new += 1
        self.found.extend(FoundRoot(complex(p), 0) for p in new[:n_new])

    def classify(self) -> None:
        """Give every new root its multiplicity.

        A point where ``|h'|`` is well above its rounding scale is a simple
        root.  The others are grouped into clusters; a certified count on a
        small disk around each cluster gives its multiplicity ``m``, and Newton
        on ``h^{(m-1)}`` polishes it.
        """
        new = [f for f in self.found if f.mult == 0]
        if not new:
            return
        suspects = self._mark_simple(new)
        clusters: dict[int, list[Cluster]] = {}
        if suspects:
            sus = _Suspects.of(suspects)
            known = _KnownRoots.of(self.found)
            for i in range(len(suspects)):
                if not sus.alive[i]:
                    continue
                cluster = self._cluster_of(sus, i, known)
                if cluster is not None:
                    clusters.setdefault(cluster.disk.multiplicity, []).append(cluster)
        self._polish(clusters)
        self.found = [f for f in self.found if f.mult > 0]

    def _mark_simple(self, new: list[FoundRoot]) -> list[FoundRoot]:
        """Mark the new roots with ``|h'|`` well above its rounding scale simple; return the others."""
        ev = self.ev
        z = np.array([f.point for f in new])
        shift = np.minimum(z.real, 0.0) * ev.tau_max
        dval = np.abs(scaled_eval(ev.dq, z, shift))
        dmag = ev.deriv_bound(z, z)
        simple = dval > 1e-5 * dmag
        for f, is_simple in zip(new, simple):
            if is_simple:
                f.mult = 1
        return [f for f, is_simple in zip(new, simple) if not is_simple]

    def _cluster_of(self, sus: _Suspects, i: int, known: _KnownRoots) -> Cluster | None:
        """The cluster of suspect ``i`` (None when its disk holds no root); its members are dropped."""
        rc = min(1e-3 * max(1.0, abs(sus.roots[i].point)), 0.25 * self.step)
        group = sus.take_group(i, rc)
        centre, disk = self._isolate(group, rc, known)
        for g in group:
            g.mult = -1  # replaced by one representative (polished below)
        if disk.multiplicity <= 0:
            return None
        sus.drop_inside(centre, disk.isolation_radius)
        return Cluster(centre, disk)

    def _isolate(self, group: list[FoundRoot], rc: float, known: _KnownRoots) -> tuple[complex, PelletDisk]:
        """A certified disk for a group of suspects: about their mean, else with the known roots near
        it taken in, else about the root of a derivative of ``h`` next to them."""
        centre = complex(np.mean([g.point for g in group]))
        rho_max = cluster_rho_max(known.points[known.alive & known.simple], centre, self.step)
        disk = pellet(self.ev.q, centre, rho_max)
        if disk is None:
            centre, disk = self._isolate_with_known(group, centre, rc, known)
        if disk is None:
            centre, disk = self._isolate_on_derivatives(centre, known)
        if disk is None:
            raise RootFindingError(f"could not isolate the root cluster near {centre:.6g}")
        return centre, disk

    def _isolate_with_known(
        self, group: list[FoundRoot], centre: complex, rc: float, known: _KnownRoots
    ) -> tuple[complex, PelletDisk | None]:
        """Retry with the roots already found within the cluster scale ``rc`` taken into the cluster.

        A cluster split by rounding (e.g. the fourfold ZV^4 zeros high up, where the float
        delays are no longer exactly commensurate) can have had one member taken for a
        simple root by an earlier pass; that root then shrinks rho_max below the cluster.
        """
        near = np.flatnonzero(known.alive & (np.abs(known.points - centre) <= rc))
        if not near.size:
            return centre, None
        centre = complex(np.mean(np.concatenate([[g.point for g in group], known.points[near]])))
        sel = known.alive & known.simple
        sel[near] = False
        rho_max = cluster_rho_max(known.points[sel], centre, self.step)
        disk = pellet(self.ev.q, centre, rho_max)
        if disk is not None and disk.multiplicity >= 1:
            known.take_back(near)
        return centre, disk

    def _isolate_on_derivatives(self, centre: complex, known: _KnownRoots) -> tuple[complex, PelletDisk | None]:
        """A disk about the root of ``h^(k)`` next to ``centre`` (k = 0, 1, ...), in a wider disk.

        Newton stalls about (rounding)^(1/m) away from an m-fold root, scattered around it
        (1e-2 for a sixfold root), so the mean of the points found can be too far off for a
        Pellet disk.  The root of h^(k) next to them is the cluster's centre for k = m - 1.
        The disk may also need to be wider than a small region's grid step (a sixfold
        cluster is 0.05 wide at s = -3): bounded by the delays' step instead, and short of
        every root already known (clusters included), so that no disk counts one twice.
        (A sixfold cluster high up, where the phase of exp(-s tau) is rounded to 1e-12, is
        0.04 wide and needs a disk of 0.3: up to the delays' step, a sixth of a chain's spacing.)
        """
        ev = self.ev
        others = known.points[known.alive]  # every root already known, clusters included
        wide = 4.0 * max(self.step, self.delay_step)
        rho_c = cluster_rho_max(others, centre, wide)
        for kd in range(0, self.max_cluster):
            dk = ev.q.derivative(kd)
            if dk.is_zero:
                break
            if kd == 0:
                c2 = centre  # first the mean itself, in the wider disk
            else:
                # a few steps suffice for a centre (Newton is linear on a multiple root of h^(k))
                zc, _ = newton(ev, np.array([centre]), rho_c, q=dk, iters=12)
                if not np.isfinite(zc[0]) or abs(zc[0] - centre) > rho_c:
                    continue
                c2 = complex(zc[0])
            disk = pellet(ev.q, c2, cluster_rho_max(others, c2, wide))
            if disk is not None and disk.multiplicity >= 1:
                return c2, disk
        return centre, None

    def _polish(self, clusters: dict[int, list[Cluster]]) -> None:
        """Polish every cluster of multiplicity m at once, on h^{(m-1)} where an m-fold root is simple."""
        ev = self.ev
        for m, items in clusters.items():
            centres = np.array([c.centre for c in items])
            radii = np.array([c.disk.radius for c in items])
            z2, ok = newton(ev, centres, radii, q=ev.q.derivative(m - 1) if m > 1 else None)
            good = ok & (np.abs(z2 - centres) < radii)
            for c, zz, g, cl in zip(centres, z2, good, items):
                self.found.append(FoundRoot(complex(zz) if g else complex(c), m, float(cl.disk.isolation_radius),
                                            complex(c)))

    def n_in(self, rect: tuple[float, float, float, float]) -> int:
        """Roots found in ``rect``, with multiplicity."""
        a, b, c, d = rect
        return sum(f.mult for f in self.found if a <= f.point.real <= b and c <= f.point.imag <= d)

    def search(self, rect: tuple[float, float, float, float], step: float) -> None:
        """Grid candidates in ``rect`` at ``step``, refined by Newton, absorbed and classified."""
        cand = grid_candidates(self.ev, rect, step)
        if cand.size:
            z, ok = newton(self.ev, cand, max_step=2.0 * step)
            # multiple roots stall Newton at rounding level: keep those points too
            # (the rounding level grows with |s| tau: the phase of exp(-s tau) is rounded)
            ok |= relative_residual(self.ev.q, z) <= np.maximum(1e-12, 64.0 * self.ev.round_factor(np.abs(z)))
            self.absorb(z[ok])
            self.classify()

    def reconcile(self, rect: tuple[float, float, float, float], count: int, step: float, depth: int) -> None:
        """Split ``rect`` until the roots found in every part add up to its certified ``count``."""
        have = self.n_in(rect)
        if have == count:
            return
        if depth > 24:
            raise RootFindingError(
                f"could not isolate the roots in {rect}: argument principle counts {count}, found {have}"
            )
        if have > count:
            raise RootFindingError(
                f"inconsistent roots in {rect}: argument principle counts {count} but {have} roots were "
                "refined there (clustered or ill-conditioned roots)"
            )
        kids, counts = self._split(rect, step, count)
        if min(counts) < 0:  # cannot happen: both boundaries are certified root-free
            raise RootFindingError(f"inconsistent counts in {rect}: {count} vs {counts}")
        for k, n in zip(kids, counts):
            if n and self.n_in(k) < n:
                # finer than the parent, but at most _MAX_SIDE nodes a side: the split itself localises
                # the missing roots, and halving the step at every level while a part shrinks only to
                # ~60 % grew the grid 4x a level (a cluster of 11 poles at |s| ~ 0.01 took minutes)
                side = max(k[1] - k[0], k[3] - k[2])
                fine = max(0.5 * min(step, side / 4.0), side / _MAX_SIDE)
                self.search(k, fine)
                self.reconcile(k, n, fine, depth + 1)

    def _split(
        self, rect: tuple[float, float, float, float], step: float, count: int
    ) -> tuple[list[tuple[float, float, float, float]], list[int]]:
        """Two parts of ``rect`` and their certified counts, cut where no root is on the cut.

        Only the first part is counted: its boundary holds the whole cut, so once it is certified
        root-free the winding numbers of the two parts add up to ``rect``'s certified ``count``
        (the cut is walked once each way), and the second part holds ``count`` minus the first's.
        """
        a, b, c, d = rect
        # split off-centre (an arbitrary irrational fraction) along the longer side
        for frac in (0.5 + 0.0731, 0.5 - 0.1127, 0.5 + 0.2213, 0.3):
            if b - a >= d - c:
                m = a + frac * (b - a)
                kids = [(a, m, c, d), (m, b, c, d)]
            else:
                m = c + frac * (d - c)
                kids = [(a, b, c, m), (a, b, m, d)]
            k0 = kids[0]
            try:
                n0 = count_in_rect(self.ev, k0, min(step, 0.5 * max(k0[1] - k0[0], k0[3] - k0[2])))
            except OnBoundary:
                continue
            return kids, [n0, count - n0]
        raise RootFindingError(f"could not split {rect} away from its roots")
