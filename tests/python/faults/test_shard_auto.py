"""`--shard auto` (DESIGN §28): the shard a CI engine's variables give —
Bazel, a Kubernetes Indexed Job, GitLab — or an error naming the variables."""

from __future__ import annotations

import pytest

from wiretape.faults import FaultInputError, Shard, from_engine


@pytest.mark.parametrize("environ, shards, expected, engine", [
    ({"TEST_SHARD_INDEX": "0", "TEST_TOTAL_SHARDS": "3"}, None, (1, 3), "bazel"),
    ({"TEST_SHARD_INDEX": "2", "TEST_TOTAL_SHARDS": "3"}, None, (3, 3), "bazel"),
    ({"JOB_COMPLETION_INDEX": "1"}, 4, (2, 4), "kubernetes"),
    ({"CI_NODE_INDEX": "1", "CI_NODE_TOTAL": "2"}, None, (1, 2), "gitlab"),
    ({"CI_NODE_INDEX": "2", "CI_NODE_TOTAL": "2"}, None, (2, 2), "gitlab"),
    # two engines that agree
    ({"TEST_SHARD_INDEX": "1", "TEST_TOTAL_SHARDS": "2", "CI_NODE_INDEX": "2",
      "CI_NODE_TOTAL": "2"}, None, (2, 2), "bazel"),
])
def test_each_engine_gives_k_and_n(environ, shards, expected, engine):
    shard = Shard.parse("auto", environ=environ, shards=shards)
    assert (shard.number, shard.count) == expected
    assert shard.engine == engine
    assert str(shard) == f"{expected[0]}/{expected[1]}"


@pytest.mark.parametrize("environ, shards, words", [
    ({}, None, ["no CI engine", "TEST_SHARD_INDEX and TEST_TOTAL_SHARDS",
                "JOB_COMPLETION_INDEX with --shards N", "CI_NODE_INDEX and CI_NODE_TOTAL"]),
    ({"TEST_SHARD_INDEX": "3", "TEST_TOTAL_SHARDS": "3"}, None,
     ["TEST_SHARD_INDEX=3", "out of range", "TEST_TOTAL_SHARDS=3", "from 0 to 2"]),
    ({"CI_NODE_INDEX": "0", "CI_NODE_TOTAL": "2"}, None, ["CI_NODE_INDEX=0", "from 1 to 2"]),
    ({"JOB_COMPLETION_INDEX": "4"}, 4, ["JOB_COMPLETION_INDEX=4", "--shards 4"]),
    ({"JOB_COMPLETION_INDEX": "0"}, None, ["JOB_COMPLETION_INDEX", "--shards N"]),
    ({"TEST_SHARD_INDEX": "1"}, None, ["TEST_SHARD_INDEX is set", "TEST_TOTAL_SHARDS is not"]),
    ({"CI_NODE_TOTAL": "3"}, None, ["CI_NODE_TOTAL is set", "CI_NODE_INDEX is not"]),
    ({"CI_NODE_INDEX": "one", "CI_NODE_TOTAL": "3"}, None, ["CI_NODE_INDEX='one'", "whole number"]),
    ({"TEST_SHARD_INDEX": "0", "TEST_TOTAL_SHARDS": "2", "CI_NODE_INDEX": "2",
      "CI_NODE_TOTAL": "2"}, None, ["bazel says shard 1/2", "gitlab says 2/2"]),
    ({"CI_NODE_INDEX": "1", "CI_NODE_TOTAL": "2"}, 3, ["--shards 3", "CI_NODE_TOTAL=2"]),
])
def test_missing_inconsistent_or_out_of_range_variables_are_named(environ, shards, words):
    with pytest.raises(FaultInputError) as refused:
        from_engine(environ, shards)
    for word in words:
        assert word in str(refused.value)


def test_bazel_is_told_the_test_shards(tmp_path):
    status = tmp_path / "shard_status"
    Shard.parse("auto", environ={"TEST_SHARD_INDEX": "0", "TEST_TOTAL_SHARDS": "2",
                                 "TEST_SHARD_STATUS_FILE": str(status)})
    assert status.exists()


def test_shards_goes_only_with_auto():
    with pytest.raises(FaultInputError, match="--shards 2 goes with --shard auto"):
        Shard.parse("1/2", shards=2)
    assert Shard.parse("1/2") == Shard.parse("auto", environ={"CI_NODE_INDEX": "1",
                                                              "CI_NODE_TOTAL": "2"})
