"""Package data: every shipped file is named in ``editor.resources``, lives inside the package,
is declared as package data (so a wheel carries it), and the CLI reaches it without paths."""

from __future__ import annotations

import fnmatch
import tomllib
from pathlib import Path

import pytest

from editor import resources
from editor.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_every_named_data_file_exists_inside_the_package():
    pkg = (ROOT / "editor").resolve()
    for name in ("MESH", "NEUTRAL_PRIOR", "SAMPLE_FACE", "DATA_README"):
        p = getattr(resources, name)
        assert p.is_file(), name
        assert p.resolve().is_relative_to(pkg), name
    for t in resources.MOUTH_TEXTURES:
        assert (resources.MOUTH_DIR / f"{t}.png").is_file()
    assert len(list(resources.PRESETS_DIR.glob("*.json"))) == 21
    assert sorted(p.name for p in resources.WEB_DIR.iterdir()) == ["app.css", "app.js",
                                                                   "index.html"]
    for old in ("resources", "presets"):  # the pre-wheel layout, outside the package
        assert not any(p.is_file() for p in (ROOT / old).rglob("*")), old


def test_package_data_globs_cover_every_data_file():
    """A data file that no ``package-data`` glob matches would be missing from the wheel."""
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"]["editor"]
    files = [p.relative_to(ROOT / "editor").as_posix()
             for p in (ROOT / "editor" / "data").rglob("*") if p.is_file()
             and "__pycache__" not in p.parts]
    assert len(files) >= 26
    missing = [f for f in files if not any(fnmatch.fnmatch(f, g) for g in globs)]
    assert missing == []


def test_shipped_presets_and_mesh_load_from_the_package():
    from editor.engine.mesh import standard_mesh
    from editor.formats.presets import shipped_preset_dir, shipped_presets

    assert shipped_preset_dir() == resources.PRESETS_DIR
    presets = shipped_presets()
    assert len(presets) == 21
    assert sum(p.kind == "emotion" for p in presets.values()) == 6
    assert standard_mesh().triangles.shape[1] == 3


def test_source_path_refuses_files_outside_the_data_folder(tmp_path):
    assert resources.source_path(resources.MESH) == resources.MESH.resolve()
    with pytest.raises(RuntimeError, match="not in a source checkout"):
        resources.source_path(tmp_path / "mesh.json")


def test_sample_keyword_renders_the_bundled_face(tmp_path):
    from editor.core import load_image

    out = tmp_path / "out.png"
    assert main(["render", "sample", "--preset", "joy", "-o", str(out)]) == 0
    assert load_image(out).shape == load_image(resources.SAMPLE_FACE).shape


def test_a_file_named_sample_wins_over_the_keyword(tmp_path, monkeypatch):
    from editor.cli.util import photo_arg

    assert photo_arg("sample") == str(resources.SAMPLE_FACE)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sample").write_bytes(b"")
    assert photo_arg("sample") == "sample"


def test_clone_eval_needs_an_explicit_jaffe_location(monkeypatch, capsys, tmp_path):
    monkeypatch.delenv(resources.JAFFE_ENV, raising=False)
    assert main(["clone-eval", "--skip-roundtrip", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--jaffe DIR" in err[0] and resources.JAFFE_ENV in err[0]
    monkeypatch.setenv(resources.JAFFE_ENV, str(tmp_path))
    assert main(["clone-eval", "--skip-roundtrip", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(tmp_path / "images") in err[0]


def test_per_user_folders_follow_env_then_platformdirs(monkeypatch, tmp_path):
    import sys

    from editor.synthesis.bilinear_photo import default_cache_dir

    monkeypatch.setenv("FAP_STUDIO_DATA_DIR", str(tmp_path / "data"))
    monkeypatch.setenv("FAP_STUDIO_CACHE", str(tmp_path / "cache"))
    assert resources.user_data_dir() == tmp_path / "data"
    assert default_cache_dir() == tmp_path / "cache"
    monkeypatch.delenv("FAP_STUDIO_DATA_DIR")
    monkeypatch.delenv("FAP_STUDIO_CACHE")
    if sys.platform.startswith("linux"):
        monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
        monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdgc"))
        assert resources.user_data_dir() == tmp_path / "xdg" / "fap-studio"
        assert default_cache_dir() == tmp_path / "xdgc" / "fap-studio"
