"""Smoke test of an installed wheel, run by .ci/run from a folder outside the repository.

Checks that ``editor`` comes from site-packages (not the source tree), that every data file is
reachable as package data (mesh, presets, mouth textures, neutral prior, sample face, AU and
ARKit mapping tables) and that
the console script renders the sample headless and exports an H.264 MP4.
"""

from __future__ import annotations

import importlib
import subprocess
import sys
import sysconfig
from pathlib import Path


def check(cond: bool, what: str) -> None:
    if not cond:
        sys.exit(f"wheel smoke test failed: {what}")
    print(f"ok: {what}")


def main() -> None:
    import av

    import editor
    from editor import resources
    from editor.core import load_image
    from editor.engine.mesh import standard_mesh
    from editor.engine.mouth import load_textures
    from editor.engine.own_expression import default_prior
    from editor.formats.presets import shipped_presets

    site = Path(sysconfig.get_paths()["purelib"]).resolve()
    check(Path(editor.__file__).resolve().is_relative_to(site),
          f"editor imported from the installed wheel ({Path(editor.__file__).parent})")
    subpackages = ("editor.cli", "editor.core", "editor.engine", "editor.formats", "editor.study",
                   "editor.synthesis", "editor.ui")
    for name in subpackages:
        importlib.import_module(name)
    check(True, f"subpackages import ({', '.join(subpackages)})")
    presets = shipped_presets()
    check(len(presets) == 21, f"21 shipped presets (got {len(presets)})")
    mesh = standard_mesh()
    check(len(mesh.names) > 100 and len(mesh.triangles) > 100,
          f"mesh loads ({len(mesh.names)} vertices, {len(mesh.triangles)} triangles)")
    check(set(load_textures()) == set(resources.MOUTH_TEXTURES), "mouth textures load")
    check(len(default_prior().names) > 0, "neutral prior loads")
    from editor.formats.arkit import arkit_table
    from editor.formats.facs import au_table

    check(len(au_table().aus) == 23 and len(arkit_table().names) == 52,
          "AU and ARKit mapping tables load (23 AUs, 52 blendshapes)")
    sample = load_image(resources.SAMPLE_FACE)
    check(all((resources.WEB_DIR / n).is_file() for n in ("index.html", "app.js", "app.css")),
          "the web rating page (index.html, app.js, app.css)")
    from editor.engine.landmarks import detect_landmarks

    lm = detect_landmarks(sample)  # the default detector's models are package data
    check(lm.detector == "mediapipe-468" and lm.mesh is not None and lm.mesh.shape == (468, 2)
          and 35 < lm.interocular < 50,
          f"MediaPipe landmarks on the sample face ({lm.detector}, IOD {lm.interocular:.1f} px)")

    exe = Path(sys.executable).parent / "fap-studio"
    out = Path("smoke.png").resolve()
    r = subprocess.run([str(exe), "render", "sample", "--preset", "joy", "-o", str(out)],
                       capture_output=True, text=True)
    check(r.returncode == 0 and load_image(out).shape == sample.shape,
          f"fap-studio render sample --preset joy ({r.stderr.strip().splitlines()[-1:]})")
    fap, mp4 = Path("smoke.fap").resolve(), Path("smoke.mp4").resolve()
    r = subprocess.run([str(exe), "fap", "export", "--preset", "surprise", "--frames", "3",
                        "-o", str(fap)], capture_output=True, text=True)
    check(r.returncode == 0, "fap-studio fap export")
    r = subprocess.run([str(exe), "animate", "sample", str(fap), "-o", str(mp4), "-q"],
                       capture_output=True, text=True)
    with av.open(str(mp4)) as c:
        ctx = c.streams.video[0].codec_context
        codec = (ctx.name, ctx.pix_fmt)
    check(r.returncode == 0 and codec == ("h264", "yuv420p"), f"animate -> MP4 {codec}")


if __name__ == "__main__":
    main()
