"""`auto`: gradient-sign corners, KKT flips, local ascent, a sample as safeguard.

Most criteria of linear elasticity are monotone in each datum over U_ad, so
the worst case sits at a vertex that the signs of dΦ/dx point to. The
steps, in scaled coordinates z ∈ P (scaling.py), with gradients on every solve:

1. Centre + safeguard (one batch): the centre of U_ad and a Latin hypercube
   of s points, s = min(2n + 1, sample.n) unless `safeguard` is given (0
   turns it off), and at most (budget − 1)/2. If some criterion has shown
   no variation at all (equal values, zero gradients: e.g. contact pressure
   where contact is open), up to two more hypercubes of s points are drawn.
   A fuzzy level (`Problem.known`: the inner levels' evaluations) draws none
   and starts from their best points.
2. Corners (one batch per round, up to 4 rounds): for each criterion not yet
   certified, v = argmax_{z∈P} g·z with g = dΦ/dz at its best point (round 1
   also from the centre when its gradient has an opposite sign somewhere) — the gradient-sign corner on a box, an LP vertex
   under A x ≤ b. New vertices of all criteria are evaluated together.
   Rounds 2–4 are the KKT check and flip: at a vertex, KKT means
   ∂Φ/∂z_i ≥ 0 where z_i = 1 and ≤ 0 where z_i = 0, i.e. the Frank–Wolfe gap
   max_{z'∈P} g·(z' − z) is 0; a violated sign moves the vertex (the LP vertex
   of the new gradient flips exactly the violators). A criterion whose
   proposed vertex was already evaluated (the signs flip back and forth: a
   maximum inside, or a non-smooth point) leaves the corner phase. A criterion whose best
   point is not smooth (its adjoint gradient one-sided: a contact switch within reach) and is
   a corner of the box gets one difference into the box per parameter there (`one_sided`),
   whose KKT sign test archive.py makes; again at the end for the final best points.
3. Local ascent (ascent.py) from the best point of every criterion still
   uncertified: trust-region projected quasi-Newton / SQP, runs in lockstep.
   On a fuzzy level (`Problem.inner`: the inner α-cut) the inner level's best
   point is first carried out, each coordinate at a bound of the inner cut
   moved to the same bound of this cut, the others kept (`_carry`): a maximum
   inside in some data and at bounds in the others follows those bounds as
   the cut grows, and the ascent from there keeps the inner level's active set.
4. A local maximum is not the maximum: for the criteria that needed step 3,
   restarts from the one-flip neighbours of the best point and the best
   vertices (`restart`), then an ascent from the best point if it is still
   uncertified. The corners' certificates end the search earlier; the budget
   caps it all. On a fuzzy level, a criterion whose ascent from its carried
   point ends at a KKT point with the carried point's active bounds skips the
   restarts, as a corner certificate does: its maximum is the inner level's,
   followed out with the bounds (the restarts of the levels inside looked for
   others; a maximum that first appears, or overtakes, between two levels is
   not looked for — the certificate is local, as ever, and the note says so).
Every outcome updates every criterion's best. Certificates: archive.py.
"""
from __future__ import annotations

import numpy as np

from ..options import Search
from .archive import Archive
from .ascent import advance, ascend, note_runs, runs_from
from .designs import lhs
from .scaling import FD_STEP, TOL

CORNER_ROUNDS = 4
FLAT_RETRIES = 2
RESTART_BASES = 3         # step 4: points whose one-flip neighbours are evaluated
RESTART_RUNS = 3          # step 4: restarted ascents per criterion
ASCENT_STEPS = 40         # steps of one ascent at most


def auto(problem, config, rng):
    cfg = Search.of(config)
    tol = cfg.kkt_tol
    archive = Archive(problem, cfg.budget)
    space = archive.space
    n = space.n

    # 1. centre + safeguard sample (unless every criterion starts from a known best)
    s = cfg.safeguard
    s = min(2 * n + 1, cfg.sample.n) if s is None else int(s)
    s = max(0, min(s, (archive.remaining - 1) // 2))
    centre = space.centre()
    warm = bool(problem.known) and all(archive.best_record(c) is not None for c in archive.criteria)
    inner_best = {c: archive.best_record(c) for c in archive.criteria}
    if warm:
        archive.note(f"started from the best of {len(problem.known)} evaluations made before (inner levels)")
    else:
        yield from archive.ask([centre, *lhs(space, s, rng)], "sample")
    for _ in range(0 if warm else FLAT_RETRIES):
        flat = [c for c in archive.criteria if archive.flat(c)]
        if not flat or s == 0 or archive.remaining < 2 * s:
            break
        archive.note(f"no variation seen of {', '.join(flat)}: {s} more samples")
        yield from archive.ask(list(lhs(space, s, rng)), "sample")

    # 2. gradient-sign corners, KKT check and flips
    open_ = [c for c in archive.criteria if not archive.certified(c, tol)]
    for round_ in range(CORNER_ROUNDS):
        if not open_ or archive.remaining == 0:
            break
        proposals, stuck = [], []
        for c in open_:
            best = archive.best_record(c)
            froms = [best] + ([archive.find(centre)] if round_ == 0 and _disagree(best, archive.find(centre), c) else [])
            new = [v for v in _vertices(space, c, froms) if archive.find(v) is None]
            proposals += new
            if not new:
                stuck.append(c)
        if not proposals:
            break
        yield from archive.ask(proposals, "corner")
        open_ = [c for c in open_ if c not in stuck and not archive.certified(c, tol)]
    yield from one_sided(archive, [c for c in archive.criteria if not archive.certified(c, tol)], tol)

    # 3. local ascent where the corners did not certify (a fuzzy level: first carry the inner maxima out)
    rest = [c for c in archive.criteria if not archive.certified(c, tol)]
    carried = {}
    if warm and problem.inner is not None and rest and archive.remaining:
        inner = [space.to_z(b) for b in problem.inner]
        zs = {c: _carry(space, inner_best[c], c, inner) for c in rest}
        recs = yield from archive.ask(list(zs.values()), "carried")
        carried = {c: r for c, r in zip(zs, recs) if r is not None}
        for c in carried:
            archive.note("the inner level's best point carried out to this cut's bounds", c)
        rest = [c for c in rest if not archive.certified(c, tol)]
    if rest and archive.remaining:
        yield from ascend(archive, [(c, archive.best_record(c)) for c in rest], tol)

    # 4. a local maximum is not the maximum: restart the ascents from one-flip neighbours,
    #    then go on from the best point of a criterion that is still uncertified; on a fuzzy
    #    level not for a maximum that kept its carried active bounds
    kept = [c for c in rest if c in carried and archive.certified(c, tol)
            and np.array_equal(_active(space, archive.best_record(c).z), _active(space, carried[c].z))]
    for c in kept:
        archive.note("restarts skipped: the maximum has the active bounds of the inner level's, carried out "
                     "(a maximum that first appears between the levels is not looked for)", c)
    rest = [c for c in rest if c not in kept]
    if rest and archive.remaining:
        yield from restart(archive, rest, tol)
    rest = [c for c in rest if not archive.certified(c, tol)]
    if rest and archive.remaining:
        yield from ascend(archive, [(c, archive.best_record(c)) for c in rest], tol, label="ascent from the best")
    yield from one_sided(archive, [c for c in archive.criteria if not archive.certified(c, tol)], tol)
    return archive.worst(tol)


def one_sided(archive, criteria, tol):
    """The one-sided differences into the box at the best point of each criterion that is not
    smooth there (`Record.nonsmooth`: its adjoint gradient is one-sided) and sits at a corner of
    the box (`Space.is_box_corner`): one solve per parameter, z_i moved by FD_STEP inward, shared
    by the criteria with the same best point; stored as `Record.inward` (q_i = ΔΦ/|Δz_i|), which
    `Archive.certify` tests for the KKT sign conditions. Skipped when the budget cannot pay
    for all of them."""
    space = archive.space
    moved = [i for i in range(space.n) if space.width[i] > 0]
    plan = {}
    for c in criteria:
        rec = archive.best_record(c)
        if rec is not None and rec.nonsmooth and c not in rec.inward and space.is_box_corner(rec.z):
            plan.setdefault(id(rec), (rec, []))[1].append(c)
    points = []
    for rec, _ in plan.values():
        for i in moved:
            z = rec.z.copy()
            z[i] += FD_STEP if z[i] == 0.0 else -FD_STEP
            points.append(z)
    if not points or len(points) > archive.remaining:
        return
    recs = iter((yield from archive.ask(points, "one-sided", gradients=False, exact=True)))
    for rec, cs in plan.values():
        got = [next(recs) for _ in moved]
        for c in cs:
            if all(o is not None and o.ok[c] for o in got):
                q = np.zeros(space.n)
                for i, o in zip(moved, got):
                    q[i] = (o.phi[c] - rec.phi[c]) / (abs(o.x[i] - rec.x[i]) / space.width[i])
                rec.inward[c] = q
                grows = [archive.problem.names[i] for i in np.argsort(-q)[:3] if q[i] > 0]
                archive.note(f"one-sided differences into the box at its best point, a non-smooth corner "
                             f"({len(moved)} solves): " + ("none grows" if archive.certified(c, tol) else
                                                           f"it grows moving {', '.join(grows)} inward"), c)


def restart(archive, criteria, tol):
    """Step 4: one round of restarts for the criteria that needed the ascent.

    From the best point of each criterion and its best evaluated vertices of P
    (RESTART_BASES in all), the one-flip neighbours (z_i → 1 − round(z_i), one
    coordinate at a time, projected onto P) are evaluated in one batch; the ascent
    then restarts, in lockstep, from each criterion's RESTART_RUNS best neighbours
    among those with a gradient that are not already KKT points. A restarted run
    that reaches a point without a gradient (non-smooth) stops there: no finite
    differences. Costs at most RESTART_BASES·n + RESTART_RUNS·40 solves per
    criterion, capped by the budget."""
    space = archive.space
    flips = [i for i in range(space.n) if space.width[i] > 0]
    neighbours = {}
    for c in criteria:
        for rec in _bases(archive, c):
            for i in flips:
                z = rec.z.copy()
                z[i] = 1.0 - np.round(z[i])
                z = space.project(z)
                neighbours.setdefault(space.key(z), z)
    if not neighbours:
        return
    recs = yield from archive.ask(list(neighbours.values()), "restart")
    done = sum(r is not None for r in recs)
    archive.note(f"restarts: {len(neighbours)} one-flip neighbours of the best points evaluated" if done == len(recs)
                 else f"restarts: {done} of the {len(neighbours)} one-flip neighbours of the best points evaluated "
                      "before the budget ran out")
    starts = []
    for c in criteria:
        ok = [r for r in recs if r is not None and r.ok[c] and r.grad.get(c) is not None
              and space.gap(r.z, r.grad[c]) > tol * archive.scale(c)]
        ok.sort(key=lambda r: -r.phi[c])
        starts += [(c, r) for r in ok[:RESTART_RUNS]]
    runs = runs_from(starts)
    yield from advance(archive, runs, tol, ASCENT_STEPS, fd=False)
    note_runs(archive, runs, "restarted ascent")


def _bases(archive, c):
    """Where the restarts flip from: the best point of c, then its best evaluated vertices of P
    (RESTART_BASES in all)."""
    best = archive.best_record(c)
    vs = [r for r in archive.records if r.ok[c] and r is not best and archive.space.is_vertex(r.z)]
    vs.sort(key=lambda r: -r.phi[c])
    return ([] if best is None else [best] + vs)[:RESTART_BASES]


def _carry(space, rec, c, inner):
    """The point of rec carried out of the inner cut (`inner`: its bounds in this cut's z):
    z_i → 0 where it sits at the inner lower bound, → 1 at the inner upper bound; where the inner
    cut is one value, to the side dΦ_c/dz_i points to (the lower one where it is 0 or unknown);
    the other coordinates kept."""
    lo, hi = inner
    z = rec.z.copy()
    g = rec.grad.get(c)
    up = np.zeros(space.n, bool) if g is None else g > 0
    at_lo, at_hi = np.abs(z - lo) <= TOL, np.abs(z - hi) <= TOL
    one = at_lo & at_hi
    z[at_lo & ~one] = 0.0
    z[at_hi & ~one] = 1.0
    z[one] = up[one]
    return z


def _active(space, z) -> np.ndarray:
    """The active set at z: −1 / +1 per coordinate at its lower / upper bound (0 inside), then
    1 per active row of A z ≤ b."""
    side = np.where(z <= TOL, -1, np.where(z >= 1 - TOL, 1, 0))
    return side if space.A is None else np.concatenate([side, space.A @ z >= space.b - TOL])


def _disagree(a, b, c) -> bool:
    """Whether the gradients of c at records a and b point opposite ways in some datum."""
    ga = a.grad.get(c) if a is not None else None
    gb = b.grad.get(c) if b is not None else None
    if ga is None or gb is None:
        return gb is not None
    return bool(np.any(np.sign(ga) * np.sign(gb) < 0))


def _vertices(space, c, records):
    """Gradient-sign (LP) vertices of criterion c from the given records."""
    out = []
    for rec in records:
        if rec is None or not rec.ok[c]:
            continue
        g = rec.grad.get(c)
        if g is None or not np.any(g):
            continue
        v = space.lp_vertex(g, rec.z)
        if not any(np.array_equal(v, w) for w in out):
            out.append(v)
    return out
