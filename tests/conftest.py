"""Shared fixtures. Qt runs offscreen unless a display platform is set explicitly."""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

import pytest  # noqa: E402

from editor.resources import SAMPLE_FACE, checkout_jaffe_dir

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = SAMPLE_FACE
JAFFE = checkout_jaffe_dir()  # $FAP_STUDIO_JAFFE, else ../shared/data/jaffe


@pytest.fixture(scope="session")
def sample_face():
    """The bundled sample as the product opens it: its own expression (an open smile) estimated,
    FAPs applied to the neutralised face."""
    from editor.core import Face

    return Face.from_image(SAMPLE)


@pytest.fixture(scope="session")
def sample_neutral():
    """The sample declared neutral (no own expression): FAP 0 = the photo's mesh. For tests of
    the engine's mechanics relative to the photo."""
    from editor.core import Face

    return Face.from_image(SAMPLE, own_expression=False)


def map_error(a, b):
    """Per pixel, the larger of the x and y differences (px) between two warps' backward maps
    (``WarpResult.maps`` of each; both must have one)."""
    import numpy as np

    assert a.maps is not None and b.maps is not None
    return np.maximum(np.abs(a.maps[0] - b.maps[0]), np.abs(a.maps[1] - b.maps[1]))


def jaffe_images(pattern: str = "*.tiff") -> list[Path]:
    if not (JAFFE / "images").is_dir():
        return []
    return sorted((JAFFE / "images").glob(pattern))


def cheek_light(g, points) -> tuple[float, float]:
    """``(light, iod)``: the median of luminance ``g`` (h, w) over two squares of cheek
    (0.24 IOD wide) 0.45 IOD under the eyes of the 68 landmarks ``points``, and their
    inter-ocular distance: the reference light of the JAFFE shading measures."""
    import numpy as np

    iod = float(np.linalg.norm(points[36:42].mean(0) - points[42:48].mean(0)))
    skin = []
    for e in (points[36:42].mean(0), points[42:48].mean(0)):
        cx, cy, r = int(e[0]), int(e[1] + 0.45 * iod), int(0.12 * iod)
        skin.append(g[cy - r:cy + r, cx - r:cx + r].ravel())
    return float(np.median(np.concatenate(skin))), iod


def eye_frame(img):
    """The face frame of ``img``'s re-detected landmarks: ``(c, ex, ey, iod)``, the eyes'
    middle, the unit vectors along and across the eyes (y down) and the inter-ocular distance
    (the frame the JAFFE shading measures sample in)."""
    import numpy as np

    from editor.engine.landmarks import detect_landmarks

    p = detect_landmarks(img).points.astype(np.float64)
    a, b = p[36:42].mean(0), p[42:48].mean(0)
    c, ex = 0.5 * (a + b), b - a
    iod = float(np.linalg.norm(ex))
    ex /= iod
    return c, ex, np.array([-ex[1], ex[0]]), iod


def frame_sample(a, frame, xs, ys):
    """``a`` (h, w) float32 sampled bilinearly on the grid ``xs`` x ``ys`` (IOD, in the
    :func:`eye_frame` ``frame``): a (len(ys), len(xs)) array."""
    import cv2
    import numpy as np

    c, ex, ey, iod = frame
    X, Y = np.meshgrid(xs, ys)
    mx = (c[0] + (X * ex[0] + Y * ey[0]) * iod).astype(np.float32)
    my = (c[1] + (X * ex[1] + Y * ey[1]) * iod).astype(np.float32)
    return cv2.remap(a, mx, my, cv2.INTER_LINEAR)


def jaffe_real_and_drawn(measure, code: str, preset: str) -> tuple[float, float]:
    """Medians of ``measure(image)`` (None: not measurable) over JAFFE's real ``code`` photos
    (e.g. "HA") and over ``preset`` at 100 % rendered on each woman's first neutral photo;
    skips the test when JAFFE is absent (or fewer than 8 renders measure)."""
    import numpy as np

    from editor.core import Face
    from editor.engine.imageio import load_image
    from editor.formats.presets import apply_preset

    real = [m for p in jaffe_images(f"*.{code}*.tiff") if (m := measure(load_image(p)))]
    drawn = [m for ne in jaffe_images("*.NE1.*.tiff")
             if (m := measure(Face.from_image(ne, own_expression=False)
                              .render(apply_preset(preset)))) is not None]
    if len(drawn) < 8:
        pytest.skip("../shared/data/jaffe is not available")
    return float(np.median(real)), float(np.median(drawn))



def jaffe_changes(measure, code: str, preset: str) -> tuple[list, list, list]:
    """``measure(image)`` on JAFFE's real ``code`` photos and on ``preset`` at 100 % and
    150 % (sharp renders) on each woman's first neutral photo, each less that neutral photo's
    own value: (real, at 100 %, at 150 %). Skips the test when JAFFE is absent (fewer than 8
    women)."""
    from editor.core import Face
    from editor.engine.imageio import load_image
    from editor.formats.presets import apply_preset

    real, ours, strong = [], [], []
    for ne in jaffe_images("*.NE1.*.tiff"):
        photos = jaffe_images(f"{ne.name[:2]}.{code}*.tiff")
        if not photos:
            continue
        f = Face.from_image(ne, own_expression=False)
        base = measure(f.image)
        real += [measure(load_image(p)) - base for p in photos]
        ours.append(measure(f.render(apply_preset(preset, 1.0), sharp=True)) - base)
        strong.append(measure(f.render(apply_preset(preset, 1.5), sharp=True)) - base)
    if len(ours) < 8:
        pytest.skip("../shared/data/jaffe is not available")
    return real, ours, strong

@pytest.fixture(scope="session")
def jaffe_faces():
    """Five JAFFE neutral faces (different people); skipped when the data is absent."""
    from editor.core import Face

    paths = jaffe_images("*.NE1.*.tiff")[:5]
    if len(paths) < 5:
        pytest.skip("../shared/data/jaffe is not available")
    return [Face.from_image(p, own_expression=False) for p in paths]


@pytest.fixture
def isolated_settings(tmp_path):
    """Point QSettings (INI format) at a folder under ``tmp_path``, never the user's."""
    from PySide6.QtCore import QSettings

    folder = tmp_path / "settings"
    QSettings.setDefaultFormat(QSettings.Format.IniFormat)
    QSettings.setPath(QSettings.Format.IniFormat, QSettings.Scope.UserScope, str(folder))
    QSettings.setPath(QSettings.Format.IniFormat, QSettings.Scope.SystemScope, str(folder))
    return folder


@pytest.fixture
def warnings(monkeypatch) -> list[str]:
    """Warning boxes never block: their texts are collected; "discard changes?" says Discard."""
    from PySide6.QtWidgets import QMessageBox

    got: list[str] = []
    monkeypatch.setattr(QMessageBox, "warning",
                        lambda _parent, _title, text, *a, **k: got.append(text))
    monkeypatch.setattr(QMessageBox, "question",  # unsaved-changes prompt at teardown
                        lambda *a, **k: QMessageBox.StandardButton.Discard)
    return got


@pytest.fixture
def model(qtbot, sample_neutral):
    """A DocumentModel holding the sample face declared neutral (every FAP starts at 0)."""
    from editor.ui.document_model import DocumentModel

    m = DocumentModel()
    m.load(sample_neutral)
    return m


@pytest.fixture
def cli(capfd):
    """Run ``fap-studio ARGS...`` in this process: ``cli("render", photo, "-o", out)`` returns a
    :class:`subprocess.CompletedProcess` (``returncode``, ``stdout``, ``stderr``) as a subprocess
    run would, with C-level output (file descriptors 1 and 2) caught too. argparse's usage
    errors (``SystemExit``) become their exit code. The real entry point keeps its own tests
    (``test_cli_gui.py``, the Ctrl-C and broken-pipe cases of ``test_robustness.py``)."""
    import subprocess

    from editor.cli import main

    def run(*args) -> subprocess.CompletedProcess:
        argv = [str(a) for a in args]
        capfd.readouterr()
        try:
            code = main(argv)
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else 1
        out, err = capfd.readouterr()
        return subprocess.CompletedProcess(["fap-studio", *argv], code, out, err)

    return run
