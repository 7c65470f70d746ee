"""The issue-15 render rows of ``python -m editor.bench`` (behaviour only, no timings)."""

from __future__ import annotations

from editor.bench import EXPRESSION, _face_at, _time_pair
from editor.bench_render import HEAD_ROTATION, Helpers, _face_wide, _face_width, _row


def test_row_schema_goal_and_ok():
    r = _row("fap_to_image_head_rotation", "1920x1080", 15.0, 10.0, 1.5)
    assert r["bench"] == "fap_to_image_head_rotation" and r["size"] == "1920x1080"
    assert r["median_ms"] == 15.0 and r["ratio"] == 1.5
    assert r["goal"] == "<= 1.5 x remap_full_frame 1920x1080" and r["ok"] is True
    assert _row("warp_plan_build", "1920x1080", 21.0, 10.0, 2.0)["ok"] is False


def test_face_wide_has_the_asked_width():
    hp = Helpers(lambda d: None, _face_at, _time_pair, EXPRESSION)
    face = _face_wide(hp, (1280, 720), 300.0)
    assert face.image.shape[:2] == (720, 1280)
    assert abs(_face_width(face) - 300.0) < 0.05 * 300.0


def test_head_rotation_row_rotates_the_head():
    assert set(HEAD_ROTATION) == {48, 49, 50} and all(HEAD_ROTATION.values())


def test_render_stages_times_every_step_and_restores_the_renderer(sample_face):
    import numpy as np

    import editor.engine.face as face_module
    from editor.bench_stages import STAGES, stage_costs
    from editor.engine.faps import FAPS

    before = {name: getattr(face_module, name) for name in STAGES.values()}
    vec = FAPS.clamp(FAPS.vector(EXPRESSION))
    ref = sample_face.render(vec)
    row = stage_costs(sample_face, vec, n=3, warm=1)
    # every step the render takes is timed (the bench expression runs each of them), and the
    # module's functions are the renderer's own again afterwards, the render unchanged
    assert set(row["steps"]) == set(STAGES) | {"rest"}
    assert all(row["steps"][s] > 0.0 for s in STAGES)
    assert {name: getattr(face_module, name) for name in STAGES.values()} == before
    assert np.array_equal(sample_face.render(vec), ref)
