"""Freeze dlib's JAFFE motion statistics for the preset tests (tests/data/jaffe_motion_dlib.json).

``python scripts/freeze_jaffe_motion.py [--jaffe DIR] [-o OUT.json] [--check]`` -- run with the
dlib extra installed (``pip install '.[dlib]'``): the emotion presets were derived from dlib's
68 landmarks (issue 14) and MediaPipe, the default detector, under-reads the brows' and lids'
motion, so its bands are not comparable. ``tests/test_presets_real.py`` measures live with dlib
when it is installed (and then fails when this file no longer matches) and reads this file
when it is not (CI).

JAFFE is licensed for non-commercial research only and is never copied into the repository:
like ``editor/data/neutral_prior.json`` (the neutral prior), only summary numbers are stored --
per emotion and measured FAP the median, p10, p90, min, max, photo count and median in pupil
distances; the p90 of the neutral noise; the joy inner-lip opening's closed/open split. No image,
landmark, per-photo or per-person value is written.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from editor.engine.landmarks import dlib_available  # noqa: E402
from editor.synthesis import jaffe_stats as js  # noqa: E402

ABOUT = ("Summary statistics of JAFFE expression motion (FAP-equivalent, FAPU) measured with "
         "dlib's 68 landmarks by editor.synthesis.jaffe_stats; written by "
         "scripts/freeze_jaffe_motion.py. JAFFE is research-only: no images, landmarks or "
         "per-photo values are stored.")
FROZEN = ROOT / "tests" / "data" / "jaffe_motion_dlib.json"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--jaffe",
                    help="JAFFE folder (default: $FAP_STUDIO_JAFFE or ../shared/data/jaffe)")
    ap.add_argument("-o", "--output", default=str(FROZEN))
    ap.add_argument("--check", action="store_true",
                    help="only compare the file with a live measurement (exit 1 when stale)")
    a = ap.parse_args()
    if not dlib_available():
        print("dlib is not installed (pip install '.[dlib]'): the frozen bands are dlib's",
              file=sys.stderr)
        return 2
    live = js.MotionSummary.of(js.measure(a.jaffe))
    if a.check:
        bad = js.MotionSummary.load(a.output).differences(live)
        print("\n".join(bad) or f"{a.output}: matches the live measurement")
        return 1 if bad else 0
    doc = {"about": ABOUT, **live.to_json()}
    text = re.sub(r"\[\s+([^\[\]{}]*?)\s+\]", lambda m: "[" + " ".join(m[1].split()) + "]",
                  json.dumps(doc, indent=1))  # one line per array
    Path(a.output).write_text(text + "\n", encoding="utf-8")
    print(f"wrote {a.output}: {len(live.emotions)} emotions x {len(live.faps)} FAPs, "
          f"{sum(int(st['n'][0]) for st in live.emotions.values())} photos, "
          f"{live.n_neutral} neutral noise samples")
    return 0


if __name__ == "__main__":
    sys.exit(main())
