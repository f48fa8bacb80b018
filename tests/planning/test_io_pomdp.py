"""The .pomdp reader on the benchmark files, on every grammar form, and on malformed input."""

from __future__ import annotations

import hashlib
import re
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rapomdp.planning.io_pomdp import PomdpParseError, format_pomdp, parse_pomdp, read_pomdp
from rapomdp.planning.memory import MemoryCapError
from tests.planning.planning_fixtures import TIGER

HEAD = "discount: 0.9\nvalues: reward\nstates: 3\nactions: 2\nobservations: 2\n"


@pytest.mark.parametrize(
    ("name", "shape"),
    [("Tiger", (3, 2, 2)), ("Hallway", (5, 60, 21)), ("Hallway2", (5, 92, 17))],
)
def test_reads_every_benchmark(benchmarks, name, shape):
    p = read_pomdp(benchmarks / f"{name}.pomdp")
    n_a, n_s, n_z = shape
    assert p.T.shape == (n_a, n_s, n_s)
    assert p.Z.shape == (n_a, n_s, n_z)
    np.testing.assert_allclose(p.T.sum(axis=2), 1.0)
    np.testing.assert_allclose(p.Z.sum(axis=2), 1.0)
    assert p.discount == pytest.approx(0.95)
    assert p.initial_belief.sum() == pytest.approx(1.0)


def test_benchmark_folder_is_fully_covered(benchmarks):
    files = sorted(f.stem for f in benchmarks.glob("*.pomdp"))
    assert files == ["Hallway", "Hallway2", "Tiger"]  # inside the repository: never skipped
    for f in files:
        assert read_pomdp(benchmarks / f"{f}.pomdp").n_states >= 2


def test_the_benchmark_files_are_the_copies_their_readme_names(benchmarks):
    """Each file's size and SHA-256 are those ``data/README.md`` records with its origin."""
    rows = re.findall(r"^\| (\w+\.pomdp) \|.*\| ([\d,]+) \| `([0-9a-f]{64})` \|$",
                      (benchmarks / "README.md").read_text(), flags=re.M)
    assert sorted(name for name, _, _ in rows) == sorted(
        f.name for f in benchmarks.glob("*.pomdp"))
    for name, size, digest in rows:
        data = (benchmarks / name).read_bytes()
        assert len(data) == int(size.replace(",", "")) < 100_000, name
        assert hashlib.sha256(data).hexdigest() == digest, name


def test_hallway_rewards_on_reaching_the_goal(benchmarks):
    p = read_pomdp(benchmarks / "Hallway.pomdp")
    # reward 1 on entering a goal state (56..59) folds into R(s, a) = P(reach goal | s, a)
    expected = p.T[:, :, 56:60].sum(axis=2)
    np.testing.assert_allclose(p.R, expected)
    # the goal states reset to the start distribution
    np.testing.assert_allclose(p.T[:, 56, :], np.broadcast_to(p.initial_belief, (5, 60)))


def test_tiger_values():
    p = parse_pomdp(TIGER)
    assert p.state_names == ["tiger-left", "tiger-right"]
    assert p.action_names == ["listen", "open-left", "open-right"]
    np.testing.assert_allclose(p.T[0], np.eye(2))
    np.testing.assert_allclose(p.T[1], 0.5)
    np.testing.assert_allclose(p.Z[0], [[0.85, 0.15], [0.15, 0.85]])
    np.testing.assert_allclose(p.R, [[-1, -1], [-100, 10], [10, -100]])
    np.testing.assert_allclose(p.initial_belief, [0.5, 0.5])


def test_all_forms_and_overrides():
    text = (
        HEAD
        + "start include: 0 2\n"
        + "T: * : * : * 0\nT: * : * : 0 1\n"  # everything to state 0 ...
        + "T: 1 : 2\n0 0.5 0.5\n"  # ... except one row
        + "O: 0\nuniform\nO: 1\n1 0\n0 1\n0.3 0.7\n"
        + "R: * : * : * : * 2\n"
        + "R: 1 : 0 : 1 : 1 10\n"  # depends on s' and o: folded into the expectation
        + "R: 0 : 1\n1 2\n3 4\n5 6\n"
    )
    p = parse_pomdp(text)
    np.testing.assert_allclose(p.initial_belief, [0.5, 0, 0.5])
    np.testing.assert_allclose(p.T[0, :, 0], 1.0)
    np.testing.assert_allclose(p.T[1, 2], [0, 0.5, 0.5])
    np.testing.assert_allclose(p.Z[0], 0.5)
    np.testing.assert_allclose(p.Z[1, 2], [0.3, 0.7])
    # R(1, 0): goes to s'=0 surely, observes 0 surely -> the override at (s'=1, o=1) never fires
    assert p.R[1, 0] == pytest.approx(2.0)
    # R(1, 2): s'=1 w.p. 0.5, then o=1 w.p. 1 -> 10; else 2
    assert p.R[1, 2] == pytest.approx(2.0)  # the override was only for start state 0
    # R(0, 1): s'=0, o uniform -> mean of row 0 of the matrix
    assert p.R[0, 1] == pytest.approx(1.5)
    assert p.R[0, 0] == pytest.approx(2.0)


def test_override_with_dependence_on_next_state():
    text = HEAD + "T: * \nuniform\nO: * \nuniform\nR: 0 : 0 : 2 : * 9\n"
    p = parse_pomdp(text)
    assert p.R[0, 0] == pytest.approx(3.0)  # 9 with probability 1/3
    assert p.R[0, 1] == pytest.approx(0.0)


def test_costs_are_negated_and_start_forms():
    base = "discount: 0.5\nvalues: cost\nstates: a b c\nactions: 1\nobservations: x\n"
    rest = "T: * \nidentity\nO: * \nuniform\nR: 0 : b : * : * 4\n"
    p = parse_pomdp(base + "start: b\n" + rest)
    np.testing.assert_allclose(p.initial_belief, [0, 1, 0])
    assert p.R[0, 1] == -4.0
    p = parse_pomdp(base + "start exclude: a\n" + rest)
    np.testing.assert_allclose(p.initial_belief, [0, 0.5, 0.5])
    p = parse_pomdp(base + "start: uniform\n" + rest)
    np.testing.assert_allclose(p.initial_belief, 1 / 3)
    p = parse_pomdp(base + "start: 0.2 0.3 0.5\n" + rest)
    np.testing.assert_allclose(p.initial_belief, [0.2, 0.3, 0.5])
    # states referenced by number although they have names
    p = parse_pomdp(base + "start: 2\n" + rest)
    np.testing.assert_allclose(p.initial_belief, [0, 0, 1])


def test_writer_round_trip():
    p = parse_pomdp(TIGER)
    q = parse_pomdp(format_pomdp(p))
    for x, y in [(p.T, q.T), (p.Z, q.Z), (p.R, q.R), (p.initial_belief, q.initial_belief)]:
        np.testing.assert_allclose(x, y)
    assert q.discount == p.discount and q.action_names == p.action_names


@pytest.mark.parametrize(
    ("text", "line", "fragment"),
    [
        (HEAD.replace("0.9", "zero"), 1, "expected a discount factor"),
        (HEAD.replace("reward", "money"), 2, "'reward' or 'cost'"),
        (HEAD + "T: 5 : 0 : 0 1\n", 6, "action index 5 is out of range"),
        (HEAD + "T: 0 : 0 : 0 1.5\n", 6, "outside [0, 1]"),
        (HEAD + "T: 0 : 0\n0.5 0.5\n", 7, "unexpected end of file"),
        (HEAD + "T: 0 : 0\n0.5 0.5 x\n", 7, "expected a probability but found 'x'"),
        (HEAD + "Q: 0\n", 6, "expected 'T:', 'O:' or 'R:'"),
        (HEAD + "T 0 : 0 : 0 1\n", 6, "expected ':'"),
        (HEAD + "O: 0 : 0\nidentity\n", 7, "expected a probability"),
        (HEAD + "O: 0\nidentity\n", 7, "only defined for T"),
        (HEAD + "T: * \nuniform\nO: * \nuniform\nR: 0 : foo : * : * 1\n", 10, "unknown state"),
        (HEAD + "T: * \nuniform\nO: * \nuniform\ndiscount: 0.5\n", 10, "must come before"),
        ("states: 2\nactions: 2\nobservations: 2\n", 3, "lacks 'discount:'"),
        (HEAD + "T: *\nuniform\nT: 0 : 1\n0.2 0.2 0.2\n", 8, "sum to 0.6"),
        (HEAD + "T: * \nuniform\n", 0, "O probabilities"),
        (HEAD + "start: 0.5 0.6 0.1\nT: *\nuniform\nO: *\nuniform\n", 6, "sums to 1.2"),
        (HEAD.replace("states: 3", "states: 0"), 3, "count must be positive"),
        ("discount: 0.9\nstates: a a\n", 2, "duplicate states"),
        ("# c\n" + HEAD.replace("discount: 0.9", "discount: 1")
         + "T: *\nuniform\nO: *\nuniform\n", 2, "discount 1 is not supported"),
    ],
)
def test_malformed_inputs_name_the_line(text, line, fragment):
    with pytest.raises(PomdpParseError) as info:
        parse_pomdp(text, source="bad.pomdp")
    assert fragment in str(info.value)
    assert info.value.line == line
    if line:
        assert f"bad.pomdp:{line}:" in str(info.value)


def test_missing_file_is_a_parse_error(tmp_path):
    with pytest.raises(PomdpParseError, match="cannot read file"):
        read_pomdp(tmp_path / "nope.pomdp")


_ALPHABET = st.sampled_from(
    ["T", "O", "R", ":", "*", " ", "\n", "0", "1", "0.5", "-1", "uniform", "identity",
     "start", "include", "exclude", "discount", "values", "states", "actions", "observations",
     "reward", "cost", "nan", "inf", "1e9", "#", "a", "b", "99999999"]
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(_ALPHABET, max_size=60), st.text(max_size=40))
def test_random_garbage_only_raises_parse_errors(tokens, noise):
    for text in (" ".join(tokens), HEAD + " ".join(tokens), HEAD + noise):
        try:
            p = parse_pomdp(text)
        except (PomdpParseError, MemoryCapError):  # huge counts: refused by their estimate
            continue
        np.testing.assert_allclose(p.T.sum(axis=2), 1.0)


def test_the_reader_is_linear_in_the_names() -> None:
    n = 100_000
    names = " ".join(f"s{i}" for i in range(n))
    text = f"discount: 0.9\nstates: {names}\nactions: a b\nobservations: x y\nT: * identity\n"
    start = time.process_time()
    with pytest.raises(MemoryCapError, match=r"100000 states x 2 actions x 2 observations, "
                                             r"dense\) needs about 320 GB"):
        parse_pomdp(text)
    dup = text.replace(f" s{n - 1}\n", " s5\n")
    with pytest.raises(PomdpParseError, match=r":2: duplicate states name\(s\): s5$"):
        parse_pomdp(dup)
    assert time.process_time() - start < 2.0  # 10^5 names twice; quadratic took minutes
    small = "discount: 0.9\nstates: " + " ".join(f"s{i}" for i in range(300)) + (
        "\nactions: a\nobservations: x\nT: a identity\nT: a : s299 : s299 0\n"
        "T: a : s299 : s0 1\nO: * uniform\n")
    p = parse_pomdp(small)
    assert p.T[0, 299, 0] == 1.0 and p.T[0, 299, 299] == 0.0  # names resolved, overwritten
    assert p.T[0, 5, 5] == 1.0


_TINY = "discount: 0.9\nstates: 2\nactions: 1\nobservations: 1\nT: 0 identity\nO: 0 uniform\n"


@pytest.mark.parametrize(("text", "fragment"), [
    (_TINY + "R: 0 : 0 : * : * 1e308\n", "reward 1e+308 is outside"),
    (_TINY + "R: 0 : 0 : * : * -2e12\n", "reward -2e+12 is outside"),
    (_TINY + "R: 0 : 0 : * : * 1_000\n", "expected a reward but found '1_000'"),
    (_TINY.replace("states: 2", "states: 1_000"), "'1_000' is neither a count"),
    (_TINY + "R: 0 : 0 : * : * infinity\n", "expected a reward but found 'infinity'"),
    (_TINY.replace("T: 0 identity", "T: 0 : 0 : 0 1_0e-1\nT: 0 : 1 : 1 1"),
     "expected a probability but found '1_0e-1'")])
def test_numbers_out_of_range_or_in_python_only_forms_are_refused(text, fragment):
    with pytest.raises(PomdpParseError, match=re.escape(fragment)):
        parse_pomdp(text, source="bad.pomdp")


def test_a_large_file_is_sized_before_it_is_read(tmp_path):
    big = tmp_path / "big.pomdp"
    with open(big, "wb") as handle:  # sparse: no data is written
        handle.truncate(2 * 10**9)
    with pytest.raises(MemoryCapError, match=r"reading .*big.pomdp \(2 GB of text\)"):
        read_pomdp(big)


def test_a_device_is_read_no_further_than_the_cap():
    with pytest.raises(PomdpParseError, match="not a regular file"):
        read_pomdp("/dev/zero", memory_gb=0.01)
