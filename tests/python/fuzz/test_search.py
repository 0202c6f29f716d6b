"""wiretape.fuzz's search (DESIGN §27): the plans come from --seed and the
run's index alone, so shards split one search's runs and a seed repeats it."""

import sys

import pytest

import wiretape
from wiretape import fuzz
from wiretape.faults import Shard


@pytest.fixture()
def session(tmp_path):
    path = tmp_path / "lines.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        writer.write("tx", 0, b"Q0\n")
        writer.write("rx", 1_000_000, b"R0\n")
        writer.write("tx", 2_000_000, b"Q1\n")
        writer.write("rx", 3_000_000, b"R1\n")
    return path


def test_plans_come_from_the_seed_and_the_index():
    assert fuzz.random_plan(7, 3, 2) == fuzz.random_plan(7, 3, 2)
    assert fuzz.random_plan(7, 3, 2) != fuzz.random_plan(8, 3, 2)
    assert all(len(fuzz.random_plan(0, index, 2)) % 4 == 0 for index in range(50))


def test_shards_split_the_runs_of_one_search(tmp_path, session):
    target = fuzz.Target([sys.executable, "-c", "pass", "{port}"], timeout=30)
    ran = {}
    for number in (1, 2):
        result = fuzz.search(str(session), target, str(tmp_path / f"findings{number}"),
                             seed=5, runs=6, shard=Shard(number, 2))
        ran[number] = [(run.case, run.where) for run in result.runs]
        assert not result.found
    assert [case for case, _ in ran[1]] == [0, 2, 4]
    assert [case for case, _ in ran[2]] == [1, 3, 5]
    for case, plan in ran[1] + ran[2]:
        assert plan == fuzz.random_plan(5, case, 2).hex()
