"""Tree files -> py_trees trees: composites, decorators, subtrees, remaps and every error."""

from __future__ import annotations

import dataclasses
import textwrap
from pathlib import Path

import py_trees
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from py_trees.common import Status
from yaml_fuzz import paths_of

from bomc_bt.errors import BomcError
from bomc_bt.tree import ClockTimeout, Leaf, Registry, load_tree


class FakeRobot:
    """A robot that is only a clock: step() advances 0.1 s."""

    def __init__(self, dt: float = 0.1):
        self.t = 0.0
        self.dt = dt
        self.terminated: list[tuple[str, Status]] = []

    def now(self) -> float:
        return self.t

    def step(self) -> None:
        self.t += self.dt


@dataclasses.dataclass(frozen=True)
class CounterParams:
    step: int = 1


class Counter(Leaf):
    """Adds ``step`` to blackboard ``count`` and succeeds."""

    Params = CounterParams
    writes = ("count",)

    def update(self) -> Status:
        self.set("count", self.get("count", 0) + self.params.step)
        return Status.SUCCESS


@dataclasses.dataclass(frozen=True)
class FailParams:
    failures: int


class FailTimes(Leaf):
    """Fails its first ``failures`` runs, then succeeds; counts attempts."""

    Params = FailParams

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.attempts = 0

    def update(self) -> Status:
        self.attempts += 1
        return Status.FAILURE if self.attempts <= self.params.failures else Status.SUCCESS


@dataclasses.dataclass(frozen=True)
class WaitParams:
    until: float


class WaitUntil(Leaf):
    """RUNNING until the robot clock reaches ``until``; records terminate() calls."""

    Params = WaitParams

    def update(self) -> Status:
        return Status.SUCCESS if self.context.now() >= self.params.until else Status.RUNNING

    def terminate(self, new_status: Status) -> None:
        self.context.terminated.append((self.name, new_status))


@dataclasses.dataclass(frozen=True)
class MoveParams:
    speed: float
    label: str = "move"


class Copy(Leaf):
    """Copies blackboard ``source`` to ``target`` (a reading and writing leaf)."""

    Params = MoveParams
    reads = ("source",)
    writes = ("target",)

    def update(self) -> Status:
        self.set("target", self.get("source"))
        return Status.SUCCESS


class Tally(Counter):
    """Counter that declares ``count`` as read too (as FindDetour does ``detours_tried``)."""

    reads = ("count",)


def make_registry() -> Registry:
    registry = Registry()
    for cls in (Counter, FailTimes, WaitUntil, Copy, Tally):
        registry.add(cls.__name__, cls)
    return registry


@pytest.fixture(autouse=True)
def clean_blackboard():
    py_trees.blackboard.Blackboard.clear()
    yield
    py_trees.blackboard.Blackboard.clear()


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def load(path: Path, robot: FakeRobot | None = None, **kwargs):
    robot = robot or FakeRobot()
    return load_tree(path, make_registry(), robot, robot.now, **kwargs)


def tick_until_done(root, robot: FakeRobot, limit: int = 1000) -> int:
    for ticks in range(1, limit + 1):
        root.tick_once()
        if root.status in (Status.SUCCESS, Status.FAILURE):
            return ticks
        robot.step()
    raise AssertionError("tree did not finish")


def board(key: str):
    return py_trees.blackboard.Blackboard.storage.get(key)


# ----------------------------------------------------------------------------- trees


def test_sequence_runs_children_in_order_and_builds_named_nodes(tmp_path):
    path = write(tmp_path, "t.yaml", """
        version: 1
        root:
          sequence: Main
          memory: true
          children:
            - {behaviour: Counter, name: One}
            - {behaviour: Counter, name: Two, params: {step: 10}}
    """)
    root = load(path)
    assert isinstance(root, py_trees.composites.Sequence) and root.memory
    assert [c.name for c in root.children] == ["One", "Two"]
    root.tick_once()
    assert root.status == Status.SUCCESS
    assert board("/count") == 11


def test_memory_false_reticks_earlier_children(tmp_path):
    """Without memory the sequence starts from the first child on every tick."""
    tree = """
        root:
          sequence: Main
          memory: {memory}
          children:
            - {{behaviour: Counter}}
            - {{behaviour: WaitUntil, params: {{until: 0.25}}}}
    """
    ticks_count = {}
    for memory in ("true", "false"):
        py_trees.blackboard.Blackboard.clear()
        robot = FakeRobot()
        root = load(write(tmp_path, f"m{memory}.yaml", tree.format(memory=memory)), robot)
        ticks = tick_until_done(root, robot)
        ticks_count[memory] = (ticks, board("/count"))
    assert ticks_count["true"] == (4, 1)  # t = 0, 0.1, 0.2, 0.3: counter ran once
    assert ticks_count["false"] == (4, 4)  # ... and every tick without memory


def test_selector_falls_back_and_parallel_policies(tmp_path):
    path = write(tmp_path, "t.yaml", """
        root:
          parallel: Both
          policy: success_on_selected
          selected: [Fallback]
          children:
            - selector: Fallback
              memory: false
              children:
                - {behaviour: FailTimes, params: {failures: 5}}
                - {behaviour: Counter}
            - {behaviour: WaitUntil, params: {until: 100.0}}
    """)
    root = load(path)
    root.tick_once()
    assert root.status == Status.SUCCESS  # only the selected child had to succeed
    assert board("/count") == 1
    path = write(tmp_path, "u.yaml", """
        root:
          parallel: All
          policy: success_on_all
          children:
            - {behaviour: Counter}
            - {behaviour: WaitUntil, params: {until: 100.0}}
    """)
    root = load(path)
    root.tick_once()
    assert root.status == Status.RUNNING


def test_retry_reruns_child_until_num_failures(tmp_path):
    tree = """
        root:
          retry: {{num_failures: {n}}}
          child: {{behaviour: FailTimes, params: {{failures: 2}}}}
    """
    robot = FakeRobot()
    root = load(write(tmp_path, "r3.yaml", tree.format(n=3)), robot)
    tick_until_done(root, robot)
    assert root.status == Status.SUCCESS and root.decorated.attempts == 3
    root = load(write(tmp_path, "r2.yaml", tree.format(n=2)), robot)
    tick_until_done(root, robot)
    assert root.status == Status.FAILURE and root.decorated.attempts == 2


def test_timeout_uses_robot_clock_not_wall_time(tmp_path):
    path = write(tmp_path, "t.yaml", """
        root:
          timeout: {duration: 600}
          name: Ten Minutes
          child: {behaviour: WaitUntil, name: Forever, params: {until: 1000000000.0}}
    """)
    robot = FakeRobot(dt=1.0)
    root = load(path, robot)
    assert isinstance(root, ClockTimeout) and root.name == "Ten Minutes"
    ticks = tick_until_done(root, robot)
    assert root.status == Status.FAILURE
    assert ticks == 601 and robot.now() == 600.0  # 600 robot seconds, microseconds of wall time
    assert robot.terminated[-1] == ("Forever", Status.INVALID)  # the child was cancelled
    assert "timed out" in root.feedback_message


def test_timeout_passes_child_result_through_in_time(tmp_path):
    path = write(tmp_path, "t.yaml", """
        root:
          timeout: {duration: 5}
          child: {behaviour: WaitUntil, params: {until: 2.0}}
    """)
    robot = FakeRobot(dt=1.0)
    root = load(path, robot)
    assert tick_until_done(root, robot) == 3 and root.status == Status.SUCCESS


def test_repeat_and_status_decorators(tmp_path):
    path = write(tmp_path, "t.yaml", """
        root:
          sequence: S
          memory: true
          children:
            - repeat: {num_success: 3}
              child: {behaviour: Counter}
            - failure_is_success:
              child: {behaviour: FailTimes, params: {failures: 9}}
            - inverter: {}
              child:
                success_is_failure:
                child: {behaviour: Counter, name: Inner, remap: {count: other}}
    """)
    robot = FakeRobot()
    root = load(path, robot)
    tick_until_done(root, robot)
    assert root.status == Status.SUCCESS
    assert board("/count") == 3 and board("/other") == 1


def test_include_subtree_reference_and_remap(tmp_path):
    write(tmp_path, "lib.yaml", """
        subtrees:
          count_twice:
            sequence: Count Twice
            memory: true
            children:
              - {behaviour: Counter, name: A}
              - {behaviour: Counter, name: B, remap: {count: b_count}}
    """)
    path = write(tmp_path, "main.yaml", """
        include: [lib.yaml]
        root:
          sequence: Main
          memory: true
          children:
            - {subtree: count_twice, name: First, remap: {count: first}}
            - {subtree: count_twice, name: Second, remap: {count: second, b_count: second_b}}
    """)
    root = load(path)
    assert [c.name for c in root.children] == ["First", "Second"]
    root.tick_once()
    assert root.status == Status.SUCCESS
    assert board("/first") == 1 and board("/second") == 1
    assert board("/b_count") == 1 and board("/second_b") == 1
    assert board("/count") is None


def test_two_instances_of_one_leaf_with_remaps_use_different_keys(tmp_path):
    py_trees.blackboard.Blackboard.set("/a", 5)
    py_trees.blackboard.Blackboard.set("/b", 7)
    path = write(tmp_path, "t.yaml", """
        root:
          sequence: S
          memory: true
          children:
            - {behaviour: Copy, name: C1, params: {speed: 1}, remap: {source: a, target: out1}}
            - {behaviour: Copy, name: C2, params: {speed: 2}, remap: {source: b, target: out2}}
    """)
    root = load(path)
    root.tick_once()
    assert (board("/out1"), board("/out2")) == (5, 7)
    assert root.children[0].params == MoveParams(speed=1.0)


def test_include_found_in_extra_search_path(tmp_path):
    shared = tmp_path / "shared"
    shared.mkdir()
    write(shared, "lib.yaml", "subtrees: {one: {behaviour: Counter}}\n")
    path = write(tmp_path, "main.yaml", "include: [lib.yaml]\nroot: {subtree: one}\n")
    with pytest.raises(BomcError, match="include file 'lib.yaml' not found"):
        load(path)
    root = load(path, extra_search_paths=[shared])
    root.tick_once()
    assert board("/count") == 1


# ---------------------------------------------------------------------------- errors


def error_for(tmp_path: Path, text: str, name: str = "bad.yaml") -> str:
    path = write(tmp_path, name, text)
    with pytest.raises(BomcError) as info:
        load(path)
    return str(info.value)


@pytest.mark.parametrize(
    "text, where, message",
    [
        ("root: {behaviour: Countr}", "root", "unknown behaviour 'Countr' (known: Copy, Counter, FailTimes"),
        ("root: {behaviour: Copy, params: {speed: 1, sped: 2}}", "root.params.sped", "unknown key"),
        ("root: {behaviour: Copy}", "root.params.speed", "missing"),
        ("root: {behaviour: Copy, params: {speed: fast}}", "root.params.speed", "wrong type"),
        ("root: {behaviour: Counter, remap: {cuont: x}}", "root.remap", "no blackboard key 'cuont'"),
        ("root: {behaviour: Counter, remap: {count: a.b}}", "root.remap", "not a blackboard key"),
        ("root: {sequence: S, children: [{behaviour: Counter}]}", "root.memory", "memory: true"),
        ("root: {selector: S, memory: 1, children: [{behaviour: Counter}]}", "root.memory", "true or false"),
        ("root: {sequence: S, memory: true, children: []}", "root.children", "non-empty list"),
        (
            "root: {sequence: S, memory: true, children: [{behaviour: Counter}, {behaviour: Counter}]}",
            "root.children[1]",
            "duplicate name 'Counter'",
        ),
        ("root: {sequence: S, memory: true, children: [3]}", "root.children[0]", "expected a node"),
        ("root: {sequence: S, memory: true, children: [{behavior: X}]}", "root.children[0]", "'behavior'"),
        ("root: {behaviour: Counter, child: {behaviour: Counter}}", "root", "unknown key 'child'"),
        ("root: {behaviour: Counter, retry: {num_failures: 2}}", "root", "exactly one kind"),
        ("root: {retry: {num_failures: 2}}", "root.child", "wraps exactly one"),
        (
            "root: {retry: {num_failures: 2}, child: [{behaviour: Counter}, {behaviour: Copy}]}",
            "root.child",
            "exactly one node, got a list of 2",
        ),
        (
            "root: {inverter: null, children: [{behaviour: Counter}]}",
            "root.children",
            "exactly one 'child:'",
        ),
        ("root: {retry: {num_failures: 0}, child: {behaviour: Counter}}", "root.retry", "at least 1"),
        ("root: {retry: {}, child: {behaviour: Counter}}", "root.retry.num_failures", "missing"),
        ("root: {timeout: {duration: -1}, child: {behaviour: Counter}}", "root.timeout.duration", "negative"),
        ("root: {parallel: P, children: [{behaviour: Counter}]}", "root.policy", "success_on_all"),
        (
            "root: {parallel: P, policy: success_on_selected, selected: [No],"
            " children: [{behaviour: Counter}]}",
            "root.selected[0]",
            "not a child name",
        ),
        ("root: {subtree: nowhere}", "root", "unknown subtree 'nowhere'"),
        ("root: {subtree: a}\nsubtrees: {a: {behaviour: Counter}}\nextra: 1", "extra", "unknown key"),
        ("version: 2\nroot: {behaviour: Counter}", "version", "unsupported format version"),
        ("name: x", "root", "missing"),
        ("include: [missing.yaml]\nroot: {behaviour: Counter}", "include[0]", "'missing.yaml' not found"),
        ("root: {sequence: 7, memory: true, children: [{behaviour: Counter}]}", "root", "non-empty string"),
        (
            "root: {subtree: a, remap: {nothing: x}}\nsubtrees: {a: {behaviour: Counter}}",
            "root.remap",
            "uses no blackboard key 'nothing'",
        ),
    ],
)
def test_malformed_trees_name_file_and_node_path(tmp_path, text, where, message):
    error = error_for(tmp_path, text)
    assert error.startswith(str(tmp_path / "bad.yaml") + ": ")
    assert f": {where}: " in error
    assert message in error


def test_yaml_syntax_error_reports_line(tmp_path):
    error = error_for(tmp_path, "root:\n  sequence: S\n  children: [a, b\n")
    assert "bad.yaml" in error and "invalid YAML" in error and "line " in error


def test_non_mapping_file(tmp_path):
    assert "must be a mapping" in error_for(tmp_path, "- just\n- a list\n")


def test_error_in_included_file_names_that_file_and_subtree_path(tmp_path):
    write(tmp_path, "lib.yaml", """
        subtrees:
          save:
            retry: {num_failures: 2}
            child: {behaviour: SaveMapp}
    """)
    error = error_for(tmp_path, "include: [lib.yaml]\nroot: {subtree: save}\n")
    expected = ": subtrees.save.child: unknown behaviour 'SaveMapp'"
    assert error.startswith(str(tmp_path / "lib.yaml") + expected)


def test_unreferenced_subtree_is_still_checked(tmp_path):
    error = error_for(tmp_path, "root: {behaviour: Counter}\nsubtrees: {spare: {behaviour: Nope}}\n")
    assert ": subtrees.spare: unknown behaviour 'Nope'" in error


def test_an_unused_subtree_with_a_key_read_and_written_is_checked_and_the_tree_loads(tmp_path):
    """Checking an unreferenced subtree builds it and unregisters its leaves' keys; py_trees'
    own unregister fails on a key a leaf both reads and writes. A user's tree that included
    traverse.yaml for its refresh subtree alone stopped with that KeyError's traceback."""
    write(tmp_path, "lib.yaml", """\
        version: 1
        subtrees:
          tally: {behaviour: Tally, ports: {reads: [count], writes: [count]}}
          count: {behaviour: Counter, params: {step: 2}}
    """)
    root = load(write(tmp_path, "main.yaml", "version: 1\ninclude: [lib.yaml]\nroot: {subtree: count}\n"))
    root.tick_once()
    assert root.status == Status.SUCCESS and board("/count") == 2
    assert not any("Tally" in name for name in py_trees.blackboard.Blackboard.clients.values())  # checked, let go


def test_subtree_cycles(tmp_path):
    error = error_for(tmp_path, "root: {subtree: a}\nsubtrees: {a: {inverter: , child: {subtree: a}}}\n")
    assert "subtrees.a.child: subtree cycle: a -> a" in error
    error = error_for(tmp_path, """
        root: {subtree: a}
        subtrees:
          a: {sequence: A, memory: true, children: [{subtree: b}]}
          b: {selector: B, memory: false, children: [{behaviour: Counter}, {subtree: a}]}
    """)
    assert "subtrees.b.children[1]: subtree cycle: a -> b -> a" in error


def test_include_cycle_and_duplicate_subtree(tmp_path):
    write(tmp_path, "a.yaml", "include: [b.yaml]\nroot: {behaviour: Counter}\n")
    write(tmp_path, "b.yaml", "include: [a.yaml]\n")
    with pytest.raises(BomcError, match=r"b\.yaml: include\[0\]: include cycle: a.yaml -> b.yaml -> a.yaml"):
        load(tmp_path / "a.yaml")
    write(tmp_path, "c.yaml", "subtrees: {x: {behaviour: Counter}}\n")
    error = error_for(tmp_path, "include: [c.yaml]\nsubtrees: {x: {behaviour: Copy}}\nroot: {subtree: x}\n")
    assert ": subtrees.x: subtree 'x' is already defined in" in error and "c.yaml" in error


def test_diamond_include_is_read_once(tmp_path):
    write(tmp_path, "base.yaml", "subtrees: {one: {behaviour: Counter}}\n")
    write(tmp_path, "left.yaml", "include: [base.yaml]\n")
    write(tmp_path, "right.yaml", "include: [base.yaml]\n")
    root = load(write(tmp_path, "top.yaml", "include: [left.yaml, right.yaml]\nroot: {subtree: one}\n"))
    assert root.name == "Counter"


def test_missing_tree_file():
    with pytest.raises(BomcError, match="nowhere.yaml: tree file not found"):
        load(Path("/nonexistent/nowhere.yaml"))


# ------------------------------------------------------------------------------ fuzz

VALID = {
    "version": 1,
    "subtrees": {"twice": {"sequence": "Twice", "memory": True, "children": [
        {"behaviour": "Counter", "name": "A"},
        {"behaviour": "Counter", "name": "B", "remap": {"count": "b"}}]}},
    "root": {"selector": "Root", "memory": False, "children": [
        {"subtree": "twice", "remap": {"count": "c"}},
        {"retry": {"num_failures": 3}, "child": {"behaviour": "FailTimes", "params": {"failures": 1}}},
        {"timeout": {"duration": 5.0}, "child": {"behaviour": "WaitUntil", "params": {"until": 2.0}}},
        {"parallel": "P", "policy": "success_on_selected", "selected": ["Copy"], "children": [
            {"behaviour": "Copy", "params": {"speed": 1.5}}, {"behaviour": "Counter"}]},
    ]},
}

WORDS = st.sampled_from([
    "root", "subtrees", "include", "version", "name", "behaviour", "subtree", "sequence", "selector",
    "parallel", "memory", "children", "child", "params", "remap", "retry", "timeout", "repeat", "inverter",
    "one_shot", "status_to_blackboard", "policy", "selected", "synchronise", "Counter", "Copy", "twice",
    "num_failures", "duration", "count", "speed", "success_on_all", "success_on_selected", "a.b", "",
])
SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(-3, 5), st.floats(allow_nan=True), WORDS, st.text(max_size=5)
)
YAML_VALUES = st.recursive(
    SCALARS,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(WORDS, inner, max_size=5)),
    max_leaves=25,
)


ALL_PATHS = [p for p in paths_of(VALID) if p]


def mutate(tree, path, action, new):
    import copy

    tree = copy.deepcopy(tree)
    parent = tree
    for step in path[:-1]:
        parent = parent[step]
    last = path[-1]
    if action == "delete":
        del parent[last]
    elif action == "replace":
        parent[last] = new
    elif isinstance(parent, dict):  # rename the key
        parent[new if isinstance(new, str) else str(new)] = parent.pop(last)
    else:
        parent.append(parent[last])  # duplicate a list item
    return tree


def assert_only_bomc_error(tmp_path: Path, text: str) -> None:
    py_trees.blackboard.Blackboard.clear()
    path = tmp_path / "fuzz.yaml"
    path.write_text(text)
    try:
        load(path)
    except BomcError as exc:
        assert str(exc).startswith(str(path)) or "lib.yaml" in str(exc)


def test_valid_fuzz_base_loads(tmp_path):
    path = tmp_path / "fuzz.yaml"
    path.write_text(yaml.safe_dump(VALID))
    assert load(path).name == "Root"


FUZZ = settings(max_examples=150, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])


@FUZZ
@given(value=YAML_VALUES)
def test_fuzz_random_yaml_only_bomc_error(tmp_path, value):
    assert_only_bomc_error(tmp_path, yaml.safe_dump({"root": value}))
    assert_only_bomc_error(tmp_path, yaml.safe_dump(value))


@FUZZ
@given(
    mutations=st.lists(
        st.tuples(st.sampled_from(ALL_PATHS), st.sampled_from(["delete", "replace", "rename"]), YAML_VALUES),
        min_size=1,
        max_size=3,
    )
)
def test_fuzz_mutated_valid_tree_only_bomc_error(tmp_path, mutations):
    tree = VALID
    for path, action, new in mutations:
        try:
            tree = mutate(tree, path, action, new)
        except (KeyError, IndexError, TypeError):
            continue  # an earlier mutation removed this path
    assert_only_bomc_error(tmp_path, yaml.safe_dump(tree))


@FUZZ
@given(text=st.text(alphabet=st.sampled_from(list("{}[]:,-&*!|>'\"#\n ab1")), max_size=60))
def test_fuzz_raw_text_only_bomc_error(tmp_path, text):
    assert_only_bomc_error(tmp_path, "root:\n  " + text)
    assert_only_bomc_error(tmp_path, text)


def test_recursive_alias_is_an_error_not_a_crash(tmp_path):
    error = error_for(tmp_path, "root: &r {inverter: null, child: *r}\n")
    assert "bad.yaml" in error and ("cycle" in error or "deeper" in error or "nested" in error)


def test_ports_must_list_exactly_the_keys_a_leaf_uses(tmp_path):
    ok = write(tmp_path, "ok.yaml", "root: {behaviour: Copy, params: {speed: 1}, remap: {target: out}, "
                                    "ports: {reads: [source], writes: [out]}}\n")
    load(ok, require_ports=True)
    bad = write(tmp_path, "bad.yaml", "root: {behaviour: Copy, params: {speed: 1}, ports: {reads: [source]}}\n")
    with pytest.raises(BomcError, match=r"root.ports.writes: writes lists \[\], but the leaf writes \['target'\]; "
                                        r"write ports: \{reads: \[source\], writes: \[target\]\}"):
        load(bad)
    missing = write(tmp_path, "missing.yaml", "root: {behaviour: Copy, params: {speed: 1}}\n")
    load(missing)  # optional unless required
    with pytest.raises(BomcError, match="root.ports: must be a mapping"):
        load(missing, require_ports=True)
