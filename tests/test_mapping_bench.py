"""The mapping benchmark runs and reports what it promises."""

from __future__ import annotations

from drivenav.mapping.bench import apartment, bench_mapping, trajectory


def test_bench_reports_timings_and_the_map() -> None:
    result = bench_mapping(frames=16, repeats=1, width=160, height=120)
    assert result["frames"] == 16 and (result["width"], result["height"]) == (160, 120)
    assert 0.0 < result["median_ms"] <= result["p90_ms"]
    assert 0.0 < result["frontier_ms"] <= result["frontier_p90_ms"]
    rows, cols = result["map_shape"]
    assert rows * 0.05 >= 13.0 and cols * 0.05 >= 13.0
    assert result["frontiers"] >= 1  # the walk east leaves the second room partly unexplored


def test_bench_scene_and_walk() -> None:
    poses = trajectory(20)
    assert len(poses) == 20 and poses[0].x == 0.0 and poses[-1].x == 2.0
    assert len(apartment().boxes) == 13
