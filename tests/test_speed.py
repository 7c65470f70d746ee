"""The restructured hot paths (issue 21) compute what the straightforward forms compute.

No timings here: the speed targets live in ``python -m editor.bench`` (``render_vs_engine``).
"""

from __future__ import annotations

import numpy as np
import pytest

from editor.engine.deform import _topology
from editor.engine.laplacian import _closest_on_triangles, landmark_map
from editor.engine.mesh import standard_mesh


def test_incidence_lists_each_vertex_triangles_in_order():
    mesh = standard_mesh()
    topo = _topology(mesh)
    tri = mesh.triangles
    T = len(tri)
    for v in range(mesh.n_vertices):
        expected = np.flatnonzero((tri == v).any(1))
        row = topo.incidence[v]
        assert np.array_equal(row[row < T], expected)
        assert (row[len(expected):] == T).all()
    assert topo.incidence is _topology(mesh).incidence  # built once per mesh
    assert not topo.incidence.flags.writeable


def test_closest_on_triangles_batch_equals_one_by_one(sample_neutral):
    v = sample_neutral.vertices.astype(np.float64)
    tri_pts = v[sample_neutral.triangles.astype(np.int64)]
    pts = np.asarray(sample_neutral.landmarks.points, np.float64)[::7]
    dist, bary = _closest_on_triangles(pts, tri_pts)
    for k, p in enumerate(pts):
        d1, b1 = _closest_on_triangles(p, tri_pts)
        assert np.array_equal(d1, dist[k])
        assert np.array_equal(b1, bary[k])


def test_landmark_map_reproduces_the_landmarks(sample_neutral):
    f = sample_neutral
    A = landmark_map(f.vertices, f.triangles, f.mesh.names, f.landmarks.points)
    assert A.shape == (68, f.plan.n_vertices)
    assert np.allclose(A.sum(1), 1.0)
    # the lip landmarks are tied to their own lip's triangles only
    got = A @ f.vertices.astype(np.float64)
    assert np.abs(got - f.landmarks.points).max() < 3.0


def test_clamp_is_clip():
    from editor.engine.fitting import clamp as clamp_m

    x = np.linspace(-2.0, 3.0, 101, dtype=np.float32).reshape(1, -1)
    for clamp in (clamp_m,):
        got = clamp(x, 0.0, 1.0)
        assert got.dtype == x.dtype
        assert np.array_equal(got, np.clip(x, 0.0, 1.0))


def test_bench_pair_timer_reports_both_clocks():
    from editor.bench import _time_pair

    r = _time_pair(lambda: sum(range(100)), lambda: None, n=3, warm=1)
    assert set(r) == {"a_ms", "a_cpu_ms", "b_ms", "b_cpu_ms"}
    assert all(v >= 0 for v in r.values())


def test_bench_only_selects_the_named_rows():
    from editor.bench import _parse_args

    assert _parse_args([]).only is None  # every row
    assert _parse_args(["--gui"]).only is None
    assert _parse_args(["--only", "render_vs_engine"]).only == {"render_vs_engine"}
    assert _parse_args(["--only=render_vs_engine,creases_cost"]).only == {"render_vs_engine",
                                                                           "creases_cost"}


def test_bench_only_refuses_an_unknown_row(capsys):
    """A mistyped row is named with the list of rows (it ran nothing before: no output)."""
    from editor.bench import ROWS, _parse_args

    with pytest.raises(SystemExit) as e:
        _parse_args(["--only", "render_vs_engin"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "unknown row: render_vs_engin" in err and "render_vs_engine" in err
    assert {"render_vs_engine", "warp_plan_build", "animate_fps"} <= set(ROWS)
