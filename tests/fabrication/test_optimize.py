"""Layer optimization helpers (foldfab.fabrication.optimize): sorting whole layers, two-opt on top of it,
simplification of only the lines that can change."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.fabrication import optimize
from foldfab.design import build_design
from foldfab.job import parse_job
from foldfab.fabrication.optimize import (KEPT_WHOLE_POINTS, _closed, _end_towards, _entries, _entry_exit, _kept_whole,
                                         _line_ends, _Onward, _onward, _ours, _reloop, _simplify, _theirs, _Walked)
from foldfab.fabrication.scoring import crease_lines


def _run(pipeline: str, lines: list[np.ndarray]) -> list[np.ndarray]:
    """``lines`` through a vpype command-line pipeline: the oracle for foldfab's direct calls."""
    import vpype as vp
    import vpype_cli

    doc = vp.Document()
    doc.add(lines, 1)
    return vpype_cli.execute(pipeline, doc).layers.get(1, vp.LineCollection()).lines


def pen_up(lines: list[np.ndarray], pen: complex) -> float:
    """Travel from ``pen`` through ``lines`` in order."""
    starts = np.array([line[0] for line in lines])
    ends = np.array([line[-1] for line in lines])
    return abs(starts[0] - pen) + float(np.abs(starts[1:] - ends[:-1]).sum())


def canonical(line: np.ndarray) -> tuple:
    """A line and its reverse give the same key."""
    forward = tuple((p.real, p.imag) for p in line)
    return min(forward, forward[::-1])


coordinate = st.floats(-500, 500, allow_nan=False).map(lambda v: round(v, 3))
point = st.builds(complex, coordinate, coordinate)
line = st.lists(point, min_size=2, max_size=5).map(lambda p: np.array(p, dtype=complex))


@settings(max_examples=60, deadline=None)
@given(lines=st.lists(line, max_size=60), window=st.integers(2, 9), pen=point, two_opt=st.booleans(),
       goal=st.none() | point)
def test_every_order_draws_every_line_once_as_it_was_or_reversed_and_two_opt_never_travels_more(
        lines, window, pen, two_opt, goal):
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(optimize, "TWO_OPT_LINES", window)
        ours = [drawn(order) for order in _ours(lines, two_opt, pen, goal)]
        greedy = [drawn(order) for order in _ours(lines, False, pen, goal)]
    assert len(ours) == (1 if goal is None or len(lines) < 2 else 2)
    for out in ours + ([_theirs(lines, two_opt, pen)] if lines else []):
        assert sorted(map(canonical, out)) == sorted(map(canonical, lines))
    for mine, plain in zip(ours, greedy):
        if lines:
            assert pen_up(mine, pen) <= pen_up(plain, pen) + 1e-9
    if len(greedy) == 2:  # walked from the goal and drawn backwards: backwards, the walk from the goal
        backwards = [line[::-1] for line in greedy[1][::-1]]
        assert pen_up(backwards, goal) == pytest.approx(pen_up(drawn(_ours(lines, False, goal, None)[0]), goal))


def drawn(order) -> list[np.ndarray]:
    """An order of :func:`_ours` as its list of lines."""
    return order.lines() if isinstance(order, _Walked) else order


@settings(max_examples=100, deadline=None)
@given(lines=st.lists(line, max_size=30), pen=point, park=point, data=st.data())
def test_an_order_by_index_measures_and_ends_as_its_list_of_lines(lines, pen, park, data):
    """The optimizer weighs a large layer's candidate orders by index (:class:`_Walked`) and makes
    only the chosen one a list of lines: by index, each candidate travels as far as its list and
    turns its last line the same way (the roll's programs are byte-identical either way)."""
    order = np.array(data.draw(st.permutations(range(len(lines)))), dtype=np.intp)
    flipped = np.array(data.draw(st.lists(st.booleans(), min_size=len(lines), max_size=len(lines))), dtype=bool)
    walked = _Walked(lines, np.column_stack(_line_ends(lines)).ravel(), order, flipped)
    onward = _Onward(np.array([park]))
    for candidate in (walked, walked.backwards()):
        as_list = candidate.lines()
        assert [a.tolist() for a in as_list] == [
            (lines[i][::-1] if turn else lines[i]).tolist() for i, turn in zip(candidate.order, candidate.flipped)]
        assert _entry_exit(candidate, pen, onward) == _entry_exit(as_list, pen, onward)
        turned = candidate.end_towards(pen, onward).lines()
        assert [a.tolist() for a in turned] == [a.tolist() for a in _end_towards(as_list, pen, onward)]
    assert [a.tolist() for a in walked.backwards().lines()] == [a[::-1].tolist() for a in walked.lines()[::-1]]


@pytest.mark.parametrize("two_opt", [False, True])
def test_vpypes_candidate_is_exactly_its_sort_from_the_nearest_line(two_opt):
    """vpype's ``linesort`` (``--two-opt``) from the line nearest the pen, foldfab's order before it
    had its own sort, is a candidate on a small layer."""
    rng = np.random.default_rng(5)
    lines = [np.array(p) for p in (rng.random((500, 2)) * 100) @ np.array([1, 1j])[:, None] + np.array([0, 3])]
    nearest = min(range(len(lines)), key=lambda i: min(abs(lines[i][0] - 7j), abs(lines[i][-1] - 7j)))
    expected = _run("linesort --two-opt" if two_opt else "linesort",
                    [lines[nearest], *lines[:nearest], *lines[nearest + 1:]])
    assert [a.tolist() for a in _theirs(lines, two_opt, 7j)] == [a.tolist() for a in expected]


def test_simplify_sends_only_bent_lines_to_vpype_and_keeps_the_order():
    straight = [np.array([0, 10]), np.array([20j, 30j])]
    bent = [np.array([0, 5 + 1e-4j, 10, 10 + 10j]), np.array([1 + 1j, 2 + 2j, 3 + 3j])]
    lines = [straight[0], bent[0], straight[1], bent[1]]
    out = _simplify(lines, 0.01)
    assert out[0] is straight[0] and out[2] is straight[1]  # not converted at all
    assert [p.tolist() for p in (out[1], out[3])] == [[0, 10, 10 + 10j], [1 + 1j, 3 + 3j]]
    assert [p.tolist() for p in out] == [p.tolist() for p in _run("linesimplify --tolerance 0.01", lines)]


small = st.integers(-40, 40).map(lambda v: v / 8)  # coarse: collinear and near-collinear points are common
bent_line = st.lists(st.builds(complex, small, small), min_size=3, max_size=8).map(lambda p: np.array(p))


@settings(max_examples=300, deadline=None)
@given(lines=st.lists(bent_line, min_size=1, max_size=12), tolerance=st.sampled_from([0.01, 0.1, 0.3, 1.0]))
def test_lines_judged_whole_are_those_vpype_leaves_alone(lines, tolerance):
    """Skipping the lines _kept_whole picks changes nothing: vpype's linesimplify returns them as
    they are, and _simplify gives what linesimplify over all the lines gives."""
    whole = _kept_whole(lines, tolerance)
    everything = _run(f"linesimplify --tolerance {tolerance}", lines)
    for line, judged, simplified in zip(lines, whole, everything, strict=True):
        if judged:
            assert simplified.tolist() == line.tolist()
    assert [p.tolist() for p in _simplify(lines, tolerance)] == [p.tolist() for p in everything]


def test_kept_whole_skips_zigzags_and_not_what_could_shorten():
    zigzag = np.array([0, 1 + 1j, 2, 3 + 1j])
    nearly_straight = np.array([0, 1 + 0.005j, 2, 3 + 1j])  # point 1 is 0.005 from chord 0-2
    closed = np.array([0, 1, 1j, 0])  # a chord of zero length
    long_line = np.arange(KEPT_WHOLE_POINTS + 1) * (1 + 0j) + 1j * (np.arange(KEPT_WHOLE_POINTS + 1) % 2)
    assert _kept_whole([zigzag, nearly_straight, closed, long_line], 0.01).tolist() == [True, False, False, False]


SQUARE = np.array([0, 100, 100 + 100j, 100j, 0])  # a closed loop, one corner on the park position


def test_a_lone_closed_loop_is_left_where_it_was_entered_so_onward_travel_runs_through_it():
    import vpype as vp

    onward = _onward([vp.LineCollection([SQUARE])], 0j, 0.025)
    pen = 90 + 10j
    # into the loop at the corner by the park position and home from there: not the corner nearest the pen
    assert onward.cost(pen) == pytest.approx(abs(pen))
    # an open line is entered at an end, the nearer one (what follows it is not looked into)
    assert _onward([vp.LineCollection([SQUARE[1:-1]])], 0j, 0.025).cost(pen) == pytest.approx(abs(pen - 100))


def test_the_last_closed_line_of_a_layer_starts_where_coming_in_and_going_on_add_up_to_least():
    pen = 90 + 10j
    home = _Onward(np.array([0j]))
    assert _reloop([SQUARE], pen, 0.025, home)[0][0] == 0  # 90.6 + 0, against 14.1 + 100 at (100, 0)
    # a closed line that is not the layer's last starts nearest the pen
    first, _ = _reloop([SQUARE, np.array([200, 300])], pen, 0.025, home)
    assert first[0] == 100 and first[-1] == 100


steps = st.lists(st.one_of(st.just("pause"), st.tuples(st.integers(1, 3), st.booleans())), max_size=8)


@settings(max_examples=100, deadline=None)
@given(steps=steps)
def test_device_steps_stop_before_each_other_tool_that_draws(steps):
    """A device without a tool changer stops before a pass that draws with another tool than
    the last pass that drew; empty passes and pauses change nothing; indices stay the plan's."""
    import vpype as vp

    from foldfab.devices import Tool
    from foldfab.fabrication.plan import Pass, Pause, PlotPlan, device_steps

    doc = vp.Document()
    plan_steps = []
    for index, step in enumerate(steps):
        if step == "pause":
            plan_steps.append(Pause("flip"))
        else:
            pen, draws = step
            doc.add(vp.LineCollection([np.array([index, index + 1j])] if draws else []), index + 1)
            plan_steps.append(Pass(index + 1, f"layer{index}", Tool(pen, None, 10.0)))
    plan = PlotPlan(doc, plan_steps, (100.0, 100.0))
    assert list(device_steps(plan, True)) == list(enumerate(plan_steps))
    out = list(device_steps(plan, False))
    assert [s for s in out if not (isinstance(s[1], Pause) and s[1].message.startswith("Load"))] == \
        list(enumerate(plan_steps))
    last = None
    for position, (index, step) in enumerate(out):
        if not isinstance(step, Pass) or not len(doc.layers.get(step.layer_id, [])):
            continue
        before = out[position - 1] if position else None
        changes = last is not None and step.tool.pen != last
        assert changes == (before is not None and before == (index, Pause(
            f"Load tool {step.tool.pen} for the {step.name} pass, then resume.")))
        last = step.tool.pen


def test_a_layer_after_a_pause_is_sorted_from_the_park_position():
    """The device parks the pen at a pause: the next layer starts at its line nearest the park
    position, not at the one nearest where the layer before ended; travel counts the way there."""
    import vpype as vp

    from foldfab.fabrication.optimize import optimize_plan, travel
    from foldfab.devices import Tool
    from foldfab.fabrication.plan import Pass, Pause, PlotPlan

    doc = vp.Document()
    doc.add(vp.LineCollection([np.array([100 + 100j, 150 + 100j])]), 1)
    doc.add(vp.LineCollection([np.array([160 + 100j, 160 + 150j]), np.array([10 + 10j, 10 + 40j])]), 2)
    tool = Tool(1, None, 10.0)
    park = 0j
    for pause, first in ((False, 160 + 100j), (True, 10 + 10j)):
        steps = [Pass(1, "valley", tool), *([Pause("flip")] if pause else []), Pass(2, "mountain", tool)]
        plan = optimize_plan(PlotPlan(doc, steps, (200.0, 200.0)), "greedy", 0.025, park)
        assert plan.document.layers[2].lines[0][0] == first
        layers = travel(plan, park)["layers"]
        if pause:
            valley_end = plan.document.layers[1].lines[-1][-1]
            assert layers["at pauses"] == pytest.approx(abs(valley_end - park) + abs(first - park))
            assert layers["between layers"] == 0
        else:
            assert "at pauses" not in layers


def test_the_goal_of_a_layer_is_the_park_position_or_the_best_way_into_a_lone_outline():
    import vpype as vp

    park = 300 + 300j
    assert _onward([], park, 0.025).goal() == park
    assert _onward([vp.LineCollection([SQUARE])], park, 0.025).goal() == 100 + 100j  # the corner nearest the park
    two = vp.LineCollection([np.array([0, 10]), np.array([50, 60])])
    assert _onward([two], park, 0.025).goal() is None  # many ways in: the walk from the pen decides


def test_the_last_layer_walked_back_from_the_park_position_travels_less():
    """A long strip's valleys then mountains, the park position at one end (as on the roll): the
    mountains walked greedily from where the valleys end finish far from the park position; also
    walked from the park position and drawn backwards, the plan travels 17% less."""
    import vpype as vp

    from foldfab.devices import Tool
    from foldfab.fabrication.optimize import optimize_plan, travel
    from foldfab.fabrication.plan import Pass, PlotPlan

    profile = ", ".join(f"[{0.3 * (i % 2)}, {0.5 * i:.2f}]" for i in range(201))
    job = parse_job(f"[profile]\npoints = [{profile}]\n[trajectory]\ntemplate = \"regular\"\n"
                    f"corners = 60\nradius = 2000\n")
    pattern = build_design(job, check_penetration=False).crease_pattern
    doc = vp.Document()
    for layer, kind in enumerate("VM", start=1):
        doc.add(vp.LineCollection(crease_lines(pattern, kind)), layer)
    ends = np.array([line[[0, -1]] for line in doc.layers[1].lines]).ravel()
    park = complex(ends.real.max(), ends.imag.max())
    plan = PlotPlan(doc, [Pass(1, "valley", Tool(1, None, 10.0)), Pass(2, "mountain", Tool(1, None, 10.0))],
                    (13000.0, 400.0))
    walked_back = travel(optimize_plan(plan, "greedy", 0.025, park), park)["total"]
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(_Onward, "goal", lambda self: None)
        forward_only = travel(optimize_plan(plan, "greedy", 0.025, park), park)["total"]
    assert walked_back < 0.9 * forward_only


# lines of one to six points on a coarse grid, so that closed ones (first point within 0.025 of the last) are common
grid_point = st.builds(complex, st.integers(-3, 3), st.integers(-3, 3))
loose_line = st.lists(grid_point, min_size=1, max_size=6).map(lambda p: np.array(p, dtype=complex))


@settings(max_examples=150, deadline=None)
@given(lines=st.lists(loose_line, max_size=12), pen=grid_point, goal=grid_point)
def test_ends_entries_and_reloop_of_a_whole_layer_are_those_of_each_line_on_its_own(lines, pen, goal):
    """The layer-wide arrays give each line's ends, entries and new start exactly as the definition
    line by line does: the ends of an open line, any vertex of a closed one, each closed line started
    at the vertex nearest where the pen comes from (the last, nearest coming in plus going on)."""
    import vpype as vp

    starts, ends = _line_ends(lines)
    assert starts.tolist() == [line[0] for line in lines] and ends.tolist() == [line[-1] for line in lines]
    expected = [line if _closed(line, 0.025) else line[[0, -1]] for line in lines]
    assert _entries(lines, 0.025).tolist() == (np.concatenate(expected).tolist() if lines else [])
    onward = _Onward(np.array([goal]))
    relooped, at = [], pen
    for index, line in enumerate(lines):
        if _closed(line, 0.025):
            cost = np.abs(line[:-1] - at) + (onward.costs(line[:-1]) if index == len(lines) - 1 else 0)
            line = vp.reloop(line, int(np.argmin(cost)))
        relooped.append(line)
        at = line[-1]
    assert [line.tolist() for line in _reloop(lines, pen, 0.025, onward)] == [line.tolist() for line in relooped]


def test_a_closed_outline_in_a_plan_starts_at_its_corner_nearest_the_pen():
    """A layer with closed lines is relooped in the plan (a layer without any skips the work)."""
    import vpype as vp

    from foldfab.devices import Tool
    from foldfab.fabrication.optimize import optimize_plan
    from foldfab.fabrication.plan import Pass, PlotPlan

    doc = vp.Document()
    doc.add(vp.LineCollection([np.array([200 + 210j, 300 + 210j])]), 1)
    doc.add(vp.LineCollection([SQUARE + 100 + 100j]), 2)  # from (300, 300), then on to (200, 210): its corner (200, 200)
    tool = Tool(1, None, 10.0)
    steps = [Pass(2, "cut", tool), Pass(1, "valley", tool)]
    plan = optimize_plan(PlotPlan(doc, steps, (400.0, 400.0)), "greedy", 0.025, 300 + 300j)
    assert plan.document.layers[2].lines[0][0] == 200 + 200j


def test_an_optimized_layer_holds_the_laid_out_lines_not_copies_and_leaves_them_as_they_were():
    """A hundred thousand copies made by vpype's ``Document.add`` cost a fifth of a second: the
    optimized plan holds the lay-out's straight lines themselves (some seen backwards), and
    nothing in the optimizer changes them."""
    import vpype as vp

    from foldfab.devices import Tool
    from foldfab.fabrication.optimize import optimize_plan
    from foldfab.fabrication.plan import Pass, PlotPlan, collection

    rng = np.random.default_rng(5)
    points = (rng.random(40) + 1j * rng.random(40)) * 100
    lines = [points[i:i + 2] for i in range(0, 40, 2)]
    doc = vp.Document()
    doc.layers[1] = collection(lines)
    before = [line.copy() for line in lines]
    plan = optimize_plan(PlotPlan(doc, [Pass(1, "valley", Tool(1, None, 10.0))], (200.0, 200.0)), "greedy", 0.025)
    result = plan.document.layers[1].lines
    assert sorted(canonical(line) for line in result) == sorted(canonical(line) for line in before)
    assert all(any(np.shares_memory(line, given) for given in lines) for line in result)
    assert all(np.array_equal(line, old) for line, old in zip(lines, before))
