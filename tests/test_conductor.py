"""The zone conductor of two-arm runs (ita.executive.conductor): claims granted in
simulated time, never two arms in one zone at once, no deadlock, the same answers
whichever arm's message arrives first, facts shared in simulated time."""

from __future__ import annotations

import itertools
import math

import click
import numpy as np
import pytest

from ita.executive.conductor import Conductor, conducted_arms, zone_grid
from ita.workcell import load_workcell

MOVE_S = 2.0


@pytest.fixture(scope="module")
def cell():
    return load_workcell()


@pytest.fixture(scope="module")
def poses(cell):
    """Random configurations of each arm (seeded) with the zones each holds there."""
    conductor = Conductor(zone_grid(cell), conducted_arms(cell))
    rng = np.random.default_rng(7)
    out = {}
    for arm in cell.arms():
        lo, hi = np.asarray(arm.joints.lower), np.asarray(arm.joints.upper)
        qs = lo + (hi - lo) * rng.random((160, len(lo)))
        out[arm.name] = [(q, conductor.body(arm.name, q)) for q in qs]
    return out


def fresh(cell) -> Conductor:
    return Conductor(zone_grid(cell), conducted_arms(cell))


def claim(conductor: Conductor, arm: str, t: float, q0, q1, seconds: float = MOVE_S):
    return conductor.receive(arm, ("claim", t, np.array([0.0, seconds]), np.stack([q0, q1])))


def granted_apart(conductor: Conductor) -> None:
    """No two arms' bodies are ever in one zone at one time: each recorded motion's sweep
    and each rest between motions (the body's zones) against the other arm's in time."""
    arms = conductor.order
    spans = {a: [] for a in arms}                       # (start, end, zones) of motions and rests
    for a in arms:
        moves = [m for m in conductor.paths if m.arm == a]
        q_prev = np.asarray(conductor.state[a].arm.home)
        t_prev = 0.0
        for m in moves:
            spans[a].append((t_prev, m.start_s, conductor.body(a, q_prev)))
            spans[a].append((m.start_s, m.end_s, conductor.swept(a, m.times, m.q)))
            q_prev, t_prev = m.q[-1], m.end_s
        spans[a].append((t_prev, math.inf, conductor.body(a, q_prev)))
    for (s0, e0, z0), (s1, e1, z1) in itertools.product(spans[arms[0]], spans[arms[1]]):
        if s0 < e1 and s1 < e0:
            assert not (z0 & z1), f"both arms hold a zone between {max(s0, s1):.2f} and {min(e0, e1):.2f} s"


def across(cell, poses):
    """A target for each arm in the zones the other holds at home, the two targets apart,
    each clear of the other arm folded (the allocation's rule)."""
    c = fresh(cell)
    a, b = c.order
    home = {n: c.body(n, c.state[n].arm.home) for n in c.order}
    folded = {n: c.body(n, c._folded(n, np.asarray(c.state[n].arm.home))) for n in c.order}
    for qa, za in poses[a]:
        if not (za & home[b]) or za & folded[b]:
            continue
        qb = next((q for q, z in poses[b] if z & home[a] and not z & folded[a] and not z & za), None)
        if qb is not None:
            return qa, qb
    pytest.skip("no crossing targets among the sampled poses")


def play(cell, targets, first: int = 0, dwell_s: float = 1.0, limit: int = 200):
    """Each arm's process as a two-arm run has it (ita.robot.controller with a gate): claim
    a motion to each target in turn (MOVE_S each), dwell there, fold when told, and at the
    end park and say done; messages sent in turn, arm `first` first.  Returns the
    conductor, the targets each arm reached and its refusals."""
    c = fresh(cell)
    names = c.order[first:] + c.order[:first]
    clock = {n: 0.0 for n in names}
    q = {n: np.asarray(c.state[n].arm.home, dtype=float) for n in names}
    todo = {n: list(targets[n]) for n in names}
    waiting: dict[str, str] = {}                     # arm -> what it asked
    reached = {n: 0 for n in names}
    refused = {n: 0 for n in names}
    finished: set[str] = set()
    retreat = {n: c.state[n].arm.retreat for n in names}

    def answer(arm: str, reply) -> None:
        kind, wait, fold, _why = reply
        clock[arm] += wait
        asked = waiting.pop(arm)
        if kind == "fold":
            clock[arm] += retreat[arm](q[arm], np.asarray(fold))[0].duration
            q[arm] = np.asarray(fold)
            inbox.extend(c.receive(arm, ("moved", clock[arm], q[arm])))
            if asked == "park":
                inbox.extend(c.receive(arm, ("done", clock[arm])))
                finished.add(arm)
            return
        if asked == "park":
            inbox.extend(c.receive(arm, ("done", clock[arm])))
            finished.add(arm)
            return
        target = todo[arm].pop(0)
        if kind == "go":
            clock[arm] += MOVE_S
            q[arm] = target
            reached[arm] += 1
            inbox.extend(c.receive(arm, ("moved", clock[arm], q[arm])))
            clock[arm] += dwell_s
        else:
            refused[arm] += 1

    inbox: list = []
    for _ in range(limit):
        if len(finished) == len(names):
            break
        for arm in names:
            if arm in waiting or arm in finished:
                continue
            if todo[arm]:
                waiting[arm] = "claim"
                inbox.extend(c.receive(arm, ("claim", clock[arm], np.array([0.0, MOVE_S]), np.stack([q[arm], todo[arm][0]]))))
            else:
                waiting[arm] = "park"
                inbox.extend(c.receive(arm, ("park", clock[arm], q[arm])))
        while inbox:
            arm, reply = inbox.pop(0)
            answer(arm, reply)
    else:
        raise AssertionError(f"no end after {limit} rounds: {waiting} wait")
    return c, reached, refused


def test_arms_sent_across_each_other_take_turns_and_never_share_a_zone(cell, poses) -> None:
    qa, qb = across(cell, poses)
    a, b = fresh(cell).order
    home = {n: np.asarray(fresh(cell).state[n].arm.home) for n in (a, b)}
    c, reached, refused = play(cell, {a: [qa, home[a]], b: [qb, home[b]]})
    assert reached == {a: 2, b: 2} and refused == {a: 0, b: 0}
    assert c.state[b].folds >= 1                     # the arm of lower priority gave way
    granted_apart(c)


def test_the_answers_do_not_depend_on_which_arm_asks_first(cell, poses) -> None:
    qa, qb = across(cell, poses)
    a, b = fresh(cell).order
    home = {n: np.asarray(fresh(cell).state[n].arm.home) for n in (a, b)}
    targets = {a: [qa, home[a], qa], b: [qb, home[b]]}
    runs = [play(cell, targets, first=k)[0] for k in (0, 1)]
    timeline = [sorted((m.arm, round(m.start_s, 9), round(m.end_s, 9), m.kind) for m in r.paths) for r in runs]
    assert timeline[0] == timeline[1]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_work_of_both_arms_ends_without_deadlock_and_apart(cell, poses, seed: int) -> None:
    """Targets drawn at random among those the allocation could give (each clear of the
    other arm folded): every one reached or, outside the rules, refused; never stuck."""
    c0 = fresh(cell)
    a, b = c0.order
    folded = {n: c0.body(n, c0._folded(n, np.asarray(c0.state[n].arm.home))) for n in (a, b)}
    rng = np.random.default_rng(seed)
    ok = {n: [q for q, z in poses[n] if not z & folded[c0.order[1 - c0.order.index(n)]]] for n in (a, b)}
    targets = {n: [ok[n][i] for i in rng.choice(len(ok[n]), 6, replace=False)] for n in (a, b)}
    c, reached, refused = play(cell, targets, limit=400)
    assert all(reached[n] + refused[n] == 6 for n in (a, b))
    granted_apart(c)


def test_a_claim_waits_for_the_other_arms_motion_to_end(cell, poses) -> None:
    c = fresh(cell)
    a, b = c.order
    home_a, home_b = c.state[a].arm.home, c.state[b].arm.home
    # a motion of the first arm, and one of the second whose space meets the first's sweep,
    # not where the first then rests
    home_held = c.body(b, home_b)
    for qa, za in poses[a][:80]:
        sweep = c.swept(a, [0.0, MOVE_S], [home_a, qa])
        if (sweep | za) & home_held or c._unsafe(a, qa) is not None:
            continue
        hit = next((q for q, z in poses[b]
                    if (want := z | c.swept(b, [0.0, MOVE_S], [home_b, q])) & sweep and not want & za), None)
        if hit is not None:
            break
    else:
        pytest.skip("no such pair among the sampled poses")
    assert claim(c, a, 0.0, home_a, qa)[0][1][0] == "go"
    got = claim(c, b, 0.5, c.state[b].arm.home, hit)
    if got:                                     # decided now: it starts when the first arm's motion ends
        assert got[0][1][0] == "go" and got[0][1][1] == pytest.approx(MOVE_S - 0.5)
    else:                                       # or when the first arm's clock passes that time
        got = c.receive(a, ("moved", MOVE_S, qa)) + claim(c, a, MOVE_S + 5.0, qa, qa + 0.01)
        mine = dict(got)[b]
        assert mine[0] == "go" and mine[1] >= MOVE_S - 0.5 - 1e-9
    granted_apart(c)


def test_an_arm_that_is_done_in_the_way_refuses_the_claim_never_waits(cell, poses) -> None:
    qa, qb = across(cell, poses)
    c = fresh(cell)
    a, b = c.order
    c.receive(a, ("done", 0.0))                   # the first arm stays at home for good
    got = dict(claim(c, b, 1.0, c.state[b].arm.home, qb))
    assert got[b][0] == "refuse" and "done" in got[b][3]


def test_a_fact_is_taken_in_simulated_time(cell) -> None:
    c = fresh(cell)
    a, b = c.order
    assert c.receive(b, ("take", 2.0, "alignment")) == []      # not posted yet: it waits
    got = c.receive(a, ("post", 30.0, "alignment", {"shift": 0.1}))
    assert got == [(b, (28.0, {"shift": 0.1}))]
    # posted before it is asked for: no wait
    assert c.receive(b, ("take", 50.0, "alignment")) == [(b, (0.0, {"shift": 0.1}))]


def test_a_fact_no_one_is_left_to_post_is_none(cell) -> None:
    c = fresh(cell)
    a, b = c.order
    c.receive(b, ("take", 2.0, "alignment"))
    assert c.receive(a, ("done", 10.0)) == [(b, (0.0, None))]


def _news(reply) -> tuple:
    """The news a conductor's answer carries (its item after the answer's own)."""
    return reply[4] if len(reply) > 4 else ()


@pytest.mark.parametrize("first", [0, 1])
def test_news_is_heard_with_the_other_arms_first_claim_at_or_after_it_whichever_arm_speaks_first(cell, first) -> None:
    """What one arm's diagnosis found of what both share (ita.robot.gate ``tell``) reaches
    the other with the answer to its first claim at that simulated time or later, once,
    and never comes back to the arm that told it; when each arm's message arrives first
    does not change who hears what with which answer."""
    c = fresh(cell)
    a, b = c.order
    ha, hb = np.asarray(c.state[a].arm.home), np.asarray(c.state[b].arm.home)
    messages = [(a, ("tell", 10.0, {"kind": "registered", "n": 1})), (b, ("claim", 5.0, np.array([0.0, 1.0]),
                                                                            np.stack([hb, hb]))), ]
    got: list = []
    for arm, m in (messages if first == 0 else messages[::-1]):
        got += c.receive(arm, m)
    (to, reply), = got
    assert to == b and reply[0] == "go" and _news(reply) == ()           # told at 10 s: not yet at 5 s
    c.receive(b, ("moved", 6.0, hb))
    c.receive(a, ("clock", 40.0))                                        # a makes no claim before 40 s
    (to, reply), = claim(c, b, 12.0, hb, hb)
    assert to == b and _news(reply) == ((10.0, {"kind": "registered", "n": 1}),)
    c.receive(b, ("moved", 14.0, hb))
    (to, reply), = claim(c, b, 15.0, hb, hb)
    assert _news(reply) == ()                                            # heard once
    c.receive(b, ("clock", 50.0))
    (to, reply), = claim(c, a, 41.0, ha, ha)
    assert to == a and _news(reply) == ()                                # not to the arm that told it


def test_a_fact_taken_comes_with_the_news_told_before_it_was_posted(cell) -> None:
    c = fresh(cell)
    a, b = c.order
    c.receive(b, ("take", 2.0, "alignment"))
    c.receive(a, ("tell", 20.0, {"kind": "tools", "conditions": {"us_probe_1": "broken"}}))
    got = c.receive(a, ("post", 30.0, "alignment", "A"))
    assert got == [(b, (28.0, "A", ((20.0, {"kind": "tools", "conditions": {"us_probe_1": "broken"}}),)))]


def test_a_registration_asked_of_an_arm_that_waits_itself_is_none_at_once(cell) -> None:
    """The arm that does not register the part asks the other for a registration (a fact
    only the other arm's work posts, ``of_work``): while that arm waits for its hand-over
    it can post none, and the asker hears so at once instead of waiting for ever; a fact
    not of work (the hand-over itself) is waited for."""
    c = fresh(cell)
    a, b = c.order
    assert c.receive(a, ("take", 96.0, f"handover:{a}")) == []
    assert c.receive(b, ("take", 151.0, f"handover:{b}")) == []          # both wait for the hand-over
    c2 = fresh(cell)
    c2.receive(a, ("take", 96.0, f"handover:{a}"))
    c2.receive(b, ("tell", 151.0, {"kind": "register", "key": "registration@151"}))
    assert c2.receive(b, ("take", 151.0, "registration@151", True)) == [(b, (0.0, None))]
    # and the arm waiting for its hand-over hears the request with it
    assert c2.receive(b, ("post", 400.0, f"handover:{a}", {"specs": ["S1"]})) == [
        (a, (304.0, {"specs": ["S1"]}, ((151.0, {"kind": "register", "key": "registration@151"}),)))]


def way_back(c: Conductor, arm: str, q) -> int:
    """The zones of `arm` folding from `q`, every way, and folded there."""
    fold = c._folded(arm, q)
    zones = c.body(arm, fold)
    for way in c.state[arm].arm.retreat(q, fold):
        zones |= c.swept(arm, way.times, way.q)
    return zones


def waiting_on_each_other(c: Conductor, poses, b_ok, a_ok, s_ok):
    """Poses where each arm will wait for the other's body: the second arm at qb, the first
    at qa, the first's next target qt meeting the second's body there and the second's
    next target qs meeting the first's, each reached from home, with the further tests
    given (b_ok(qb, zb), a_ok(qa, za, qb, zb), s_ok(qs, zs, qa, qb)); None when the sample
    has none."""
    a, b = c.order
    home_a, home_b = np.asarray(c.state[a].arm.home), np.asarray(c.state[b].arm.home)
    for qb, zb in poses[b][:60]:
        if (c.swept(b, [0.0, MOVE_S], [home_b, qb]) | zb) & c.body(a, home_a) or not b_ok(qb, zb):
            continue
        for qa, za in poses[a][:80]:
            if (c.swept(a, [0.0, MOVE_S], [home_a, qa]) | za) & zb or not a_ok(qa, za, qb, zb):
                continue
            qt = next((q for q, z in poses[a] if z & zb), None)          # where the first arm goes next
            qs = next((q for q, z in poses[b] if z & za and s_ok(q, z, qa, qb)), None)
            if qt is not None and qs is not None:
                return qa, qb, qt, qs
    return None


def start_waiting(c: Conductor, qa, qb, qt, qs, pinned: bool = False) -> dict:
    """Both arms to their poses, the first claims qt (decided later), then the second
    claims qs: the replies then due, by arm."""
    a, b = c.order
    home_a, home_b = np.asarray(c.state[a].arm.home), np.asarray(c.state[b].arm.home)
    assert claim(c, b, 0.0, home_b, qb)[0][1][0] == "go"
    c.receive(b, ("moved", MOVE_S, qb))
    assert claim(c, a, MOVE_S, home_a, qa)[0][1][0] == "go"
    c.receive(a, ("moved", 2 * MOVE_S, qa))
    assert claim(c, a, 2 * MOVE_S, qa, qt) == []                  # decided when the second arm's clock is there
    return dict(c.receive(b, ("claim", 2 * MOVE_S, np.array([0.0, MOVE_S]), np.stack([qb, qs]), pinned)))


def first_folds_then_second_goes(c: Conductor, got: dict, qa) -> None:
    a, b = c.order
    assert b not in got or got[b][0] != "fold"
    assert got[a][0] == "fold"                                    # the first arm folds first
    if b not in got:                   # decided once the first arm says it has folded
        fold = np.asarray(got[a][2])
        d = max(w.duration for w in c.state[a].arm.retreat(qa, fold))
        got = dict(c.receive(a, ("moved", 2 * MOVE_S + got[a][1] + d, fold)))
    assert got[b][0] == "go"                                      # then the second arm goes on
    assert c.state[a].refused == c.state[b].refused == 0 and c.state[b].folds == 0
    granted_apart(c)


def test_when_the_lower_arms_way_back_meets_the_first_arms_body_the_first_folds_first(cell, poses) -> None:
    """Each arm waits for the other's body, and the second arm cannot fold (the first arm's
    body stands on its way back): the first arm folds, and the second goes on."""
    c = fresh(cell)
    a, b = c.order
    found = waiting_on_each_other(
        c, poses, lambda qb, zb: True,
        lambda qa, za, qb, zb: za & way_back(c, b, qb) and not way_back(c, a, qa) & zb,
        lambda qs, zs, qa, qb: not (zs | c.swept(b, [0.0, MOVE_S], [qb, qs])) & c.body(a, c._folded(a, qa)))
    if found is None:
        pytest.skip("no such poses among the sampled ones")
    qa, qb, qt, qs = found
    first_folds_then_second_goes(c, start_waiting(c, qa, qb, qt, qs), qa)


def test_when_neither_arm_can_fold_the_first_arm_refused_once_has_the_lower_arms_claim_refused(cell, poses) -> None:
    """Each arm waits for the other's body and neither can fold (a fold stopped short, say):
    the claim just made is refused, the first arm's too; but once the first arm was refused
    so and has not moved, the lower arm's claim is refused instead and the first arm's
    waits for the lower's next one (before, the first arm went on refused through the rest
    of its share while it stood there)."""
    c = fresh(cell)
    a, b = c.order
    found = waiting_on_each_other(c, poses, lambda qb, zb: True, lambda qa, za, qb, zb: True,
                                  lambda qs, zs, qa, qb: True)
    if found is None:
        pytest.skip("no such poses among the sampled ones")
    qa, qb, qt, qs = found
    c._try_fold = lambda name, claim, to=None: name                # neither can fold from where it stands
    home_a, home_b = np.asarray(c.state[a].arm.home), np.asarray(c.state[b].arm.home)
    assert claim(c, b, 0.0, home_b, qb)[0][1][0] == "go"
    c.receive(b, ("moved", MOVE_S, qb))
    assert claim(c, a, MOVE_S, home_a, qa)[0][1][0] == "go"
    c.receive(a, ("moved", 2 * MOVE_S, qa))
    # the second arm asks first (it waits for the first arm's body), then the first arm:
    # the first arm's claim is refused, it stands still and asks again
    assert claim(c, b, 2 * MOVE_S, qb, qs) == []
    first = dict(claim(c, a, 2 * MOVE_S, qa, qt))
    assert set(first) == {a} and first[a][0] == "refuse" and "neither arm can give way" in first[a][3]
    got = dict(claim(c, a, 2 * MOVE_S, qa, qt))
    assert set(got) == {b} and got[b][0] == "refuse" and "neither arm can give way" in got[b][3]
    assert c.state[a].refused == 1 and c.state[b].refused == 1 and c.state[a].pending is not None
    # its next claim is decided as any (still in the way: refused too), and the first arm's
    # is answered once the second arm is done: never waited for for ever
    assert dict(claim(c, b, 2 * MOVE_S, qb, home_b))[b][0] == "refuse" and c.state[a].pending is not None
    assert dict(c.receive(b, ("done", 2 * MOVE_S)))[a][0] == "refuse"
    granted_apart(c)


def test_an_arm_whose_probe_is_on_the_part_is_never_told_to_fold(cell, poses) -> None:
    """Each arm waits for the other's body; the second would fold (the lower arm gives
    way), but its claim is pinned (a retract: its probe is pressed on the part, and a fold
    would drag it): the first arm folds instead, and the second takes its probe off."""
    c0 = fresh(cell)
    a, b = c0.order
    found = waiting_on_each_other(
        c0, poses, lambda qb, zb: not way_back(c0, b, qb) & c0.body(a, np.asarray(c0.state[a].arm.home)),
        lambda qa, za, qb, zb: not way_back(c0, a, qa) & zb and not way_back(c0, b, qb) & za,
        lambda qs, zs, qa, qb: not (zs | c0.swept(b, [0.0, MOVE_S], [qb, qs])) & c0.body(a, c0._folded(a, qa)))
    if found is None:
        pytest.skip("no such poses among the sampled ones")
    qa, qb, qt, qs = found
    assert start_waiting(fresh(cell), qa, qb, qt, qs)[b][0] == "fold"      # the rule: the lower arm gives way
    c = fresh(cell)
    first_folds_then_second_goes(c, start_waiting(c, qa, qb, qt, qs, pinned=True), qa)


def test_a_lower_arm_that_cannot_fold_for_the_first_arms_body_has_the_first_fold_first(cell, poses) -> None:
    """The first arm waits for the second's body; the second's next claim would leave it in
    the first's way still, so it should give way, but the first arm's body stands on its
    way back: the first arm folds (once), instead of the second going on with its claims
    while the first waits for its whole share; then the second gives way."""
    c0 = fresh(cell)
    a, b = c0.order
    home_a, home_b = np.asarray(c0.state[a].arm.home), np.asarray(c0.state[b].arm.home)
    found = None
    for qb, zb in poses[b][:60]:
        if (c0.swept(b, [0.0, MOVE_S], [home_b, qb]) | zb) & c0.body(a, home_a):
            continue
        for qa, za in poses[a][:80]:
            if ((c0.swept(a, [0.0, MOVE_S], [home_a, qa]) | za) & zb or not za & way_back(c0, b, qb)
                    or way_back(c0, a, qa) & zb):
                continue
            qt = next((q for q, z in poses[a] if z & zb), None)           # the first arm's next pose: in the way
            if qt is None:
                continue
            wanted = c0.swept(a, [0.0, MOVE_S], [qa, qt]) | c0.body(a, qt)
            folded_a = c0.body(a, c0._folded(a, qa))
            if way_back(c0, b, qb) & folded_a:
                continue
            qs = next((q for q, z in poses[b] if (c0.swept(b, [0.0, MOVE_S], [qb, q]) | z) & wanted
                       and not (c0.swept(b, [0.0, MOVE_S], [qb, q]) | z) & (za | folded_a)), None)
            if qs is not None:
                found = (qa, qb, qt, qs)
                break
        if found:
            break
    if found is None:
        pytest.skip("no such poses among the sampled ones")
    qa, qb, qt, qs = found
    c = fresh(cell)
    got = start_waiting(c, qa, qb, qt, qs)
    assert a in got and got[a][0] == "fold" and b not in got       # the first arm folds; the second's claim waits
    fold = np.asarray(got[a][2])
    d = max(w.duration for w in c.state[a].arm.retreat(qa, fold))
    t = 2 * MOVE_S + got[a][1] + d
    assert c.receive(a, ("moved", t, fold)) == []                   # the second waits for its next claim
    got = dict(claim(c, a, t, fold, qt))
    assert got == {b: got[b]} and got[b][0] == "fold"               # then the second gives way
    assert c.state[a].folds == c.state[b].folds == 1 and c.state[a].refused == c.state[b].refused == 0
    granted_apart(c)


def test_an_inject_script_may_name_the_arm_it_hits() -> None:
    from ita.cli.arms import scripts_of

    got = scripts_of(["t3_b:controller_failed:after=600", "broken_probe@us_probe_1:after=120", "transient"],
                     ["t3", "t3_b"])
    assert got == {"t3": ["broken_probe@us_probe_1:after=120", "transient"],
                   "t3_b": ["controller_failed:after=600", "broken_probe@us_probe_1:after=120", "transient"]}
    with pytest.raises(click.UsageError, match="no arm 'robot9'"):
        scripts_of(["robot9:controller_failed"], ["t3", "t3_b"])
    # the part is one for both arms: a knock of it lands in each arm's simulator, never one's
    assert scripts_of(["part_displaced:after=150"], ["t3", "t3_b"]) == {
        "t3": ["part_displaced:after=150"], "t3_b": ["part_displaced:after=150"]}
    with pytest.raises(click.UsageError, match="both arms share the part"):
        scripts_of(["t3_b:part_displaced:after=150"], ["t3", "t3_b"])


def test_claims_the_other_arm_refused_do_not_raise_the_alarm_of_failures_in_a_row() -> None:
    from ita.robot.controller import REFUSED_BY_ZONES
    from ita.toplevel.recording import FailuresInARow

    row = FailuresInARow(3)
    for k in range(5):
        row.not_done(f"S{k}", f"exception: REJECTED: {REFUSED_BY_ZONES}: t3_b is done and stands in the way")
    assert row.alarm == ""                  # the other arm stood in the way: not this arm failing
    for k in range(3):
        row.not_done(f"T{k}", "exception: TIMEOUT (no reply from the controller within 5.0 s)")
    assert "3 measurements in a row" in row.alarm


def test_a_sweep_is_densified_at_the_points_linspace_gives() -> None:
    """The conductor's densified knots (one array, no loop) are the knots cut as the loop of
    np.linspace cut them, to the bit: the zones a claim sweeps did not change with it."""
    from ita.executive.conductor import _densified

    rng = np.random.default_rng(2)
    q = np.cumsum(rng.normal(0.0, 0.3, size=(9, 6)), axis=0)
    q[4] = q[3]                                                    # a knot repeated: one step
    per_rad = 23.7
    pieces = [q[:1]]
    for a, b in zip(q[:-1], q[1:]):
        n = max(1, math.ceil(float(np.max(np.abs(b - a))) * per_rad))
        pieces.append(a + np.linspace(0.0, 1.0, n + 1)[1:, None] * (b - a))
    assert np.array_equal(_densified(q, per_rad), np.concatenate(pieces))


def test_an_arms_clock_lets_the_other_arms_claim_be_decided_without_its_next_claim(cell) -> None:
    """A claim at 5 s waits while the other arm may still act before then; the other's
    clock passing 5 s (ita.robot.gate's ``clock``) decides it, as its next claim would."""
    c = fresh(cell)
    a, b = c.order
    c.receive(b, ("moved", 1.0, np.asarray(c.state[b].arm.home)))
    home = np.asarray(c.state[a].arm.home)
    assert claim(c, a, 5.0, home, home + 0.01) == []            # b may claim before 5 s
    assert c.receive(b, ("clock", 4.9)) == []
    replies = c.receive(b, ("clock", 5.2))
    assert [(arm, r[0]) for arm, r in replies] == [(a, "go")]


def test_the_gate_tells_its_clock_only_past_what_the_conductor_knows() -> None:
    """The arm's clock is sent when it passes the last granted motion's end (or message)
    by CLOCK_STEP_S; not every control period."""
    from ita.robot.gate import CLOCK_STEP_S, RemoteGate

    sent = []

    class Line:
        def send(self, message):
            sent.append(message)

        def recv(self):
            return ("go", 1.0, None, "")

    gate = RemoteGate(Line())                         # type: ignore[arg-type]
    gate.claim(2.0, np.array([0.0, 3.0]), np.zeros((2, 6)))   # goes at 3 s, ends at 6 s
    for t in np.arange(2.0, 6.0 + CLOCK_STEP_S, 0.008):       # its control periods
        gate.clock(float(t))
    assert [m for m in sent if m[0] == "clock"] == []
    gate.clock(6.0 + CLOCK_STEP_S / 2)
    gate.clock(6.0 + CLOCK_STEP_S + 0.01)
    assert [m[0] for m in sent] == ["claim", "clock"] and sent[-1][1] == pytest.approx(6.0 + CLOCK_STEP_S + 0.01)


def test_a_claim_the_other_arms_zones_refused_is_no_fault_of_the_cell_to_diagnose() -> None:
    """REJECTED by the zone conductor (the two arms stood in each other's way) is not a
    tool that did not latch: no exception of kb/faults.pl, so no tests and no repair (the
    measurement stays not done and the run takes it once more before it ends); the same
    reply without the conductor's words still is one."""
    from types import SimpleNamespace

    from ita.diagnosis.classify import classify
    from ita.executive.executor import FailureKind
    from ita.logic.terms import Term
    from ita.robot.controller import REFUSED_BY_ZONES

    def failed(text: str) -> SimpleNamespace:
        failure = SimpleNamespace(
            kind=FailureKind.EXCEPTION, reason=f"exception: step 1 leave_view(t3, S-1): REJECTED(rejected) ({text})",
            reply=SimpleNamespace(payload=Term("REJECTED", ("rejected",))),
            command=SimpleNamespace(name="MOVE", stream=SimpleNamespace(device="path_planner", unit="t3")))
        return SimpleNamespace(report=SimpleNamespace(failure=failure))

    refused = failed(f"{REFUSED_BY_ZONES}: t3 stands in the way and neither arm can give way")
    assert classify(refused, held="slra_2", tool="slra_2", tool_class="slra_tool") is None
    latched = classify(failed("not holding slra_2"), held="slra_2", tool="slra_2", tool_class="slra_tool")
    assert latched is not None and latched.exception == "tool_not_seated"
