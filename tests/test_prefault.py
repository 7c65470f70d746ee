"""The pre-faulted frame buffer (:mod:`editor.engine.prefault`): a copy in it is the copy; the
threads it and the large-photo steps run on (:mod:`editor.engine.threads`)."""

from __future__ import annotations

import numpy as np

from editor.engine import prefault


def test_copy_of_uses_the_reserved_buffer_once(monkeypatch):
    monkeypatch.setattr(prefault, "MIN_BYTES", 0)
    monkeypatch.setattr(prefault, "_SPARE", [])
    img = np.random.default_rng(3).integers(0, 256, (37, 53, 3), np.uint8)
    img.setflags(write=False)
    prefault.reserve(img.shape, img.dtype)
    first = prefault.copy_of(img)
    assert np.array_equal(first, img) and first.flags.c_contiguous and first.flags.writeable
    assert not np.shares_memory(first, img)
    assert not prefault._SPARE  # handed out once
    second = prefault.copy_of(img)
    assert np.array_equal(second, img) and not np.shares_memory(second, first)


def test_copy_of_other_shapes_and_small_frames(monkeypatch):
    monkeypatch.setattr(prefault, "_SPARE", [])
    img = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
    prefault.reserve(img.shape)  # below MIN_BYTES: nothing reserved
    assert not prefault._SPARE
    monkeypatch.setattr(prefault, "MIN_BYTES", 0)
    prefault.reserve((4, 3, 3))
    out = prefault.copy_of(img)  # another shape: a plain copy, the buffer stays
    assert np.array_equal(out, img) and len(prefault._SPARE) == 1
    prefault.reserve((2, 3, 3), np.float32)  # replaces it; another type: a plain copy too
    assert np.array_equal(prefault.copy_of(img), img) and len(prefault._SPARE) == 1


def test_pending_returns_the_value_or_raises_the_error():
    from editor.engine.threads import Pending

    assert Pending(divmod, 7, 2).result() == (3, 1)
    p = Pending(divmod, 1, 0)
    try:
        p.result()
    except ZeroDivisionError:
        pass
    else:  # pragma: no cover
        raise AssertionError("the thread's exception was not raised")


def test_copy_of_when_the_touching_did_not_finish(monkeypatch):
    # (a process forked while the thread touched the buffer: the child's thread is gone)
    from editor.engine.threads import Pending

    monkeypatch.setattr(prefault, "MIN_BYTES", 0)
    monkeypatch.setattr(prefault, "_SPARE", [])
    img = np.ones((5, 4, 3), np.uint8)
    prefault.reserve(img.shape)
    gone = Pending(lambda: None)
    gone.result()
    gone._out.clear()  # as after the fork: stopped, neither a value nor an error
    prefault._SPARE[0] = prefault._SPARE[0][:2] + (gone,)
    out = prefault.copy_of(img)
    assert np.array_equal(out, img) and not np.shares_memory(out, img)
