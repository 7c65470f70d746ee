"""The render route of ``study create``: faces x presets x intensities, stored in the study."""

from __future__ import annotations

import argparse

import cv2
import numpy as np
from conftest import SAMPLE

from editor.cli.study import add_study_parser
from editor.formats.presets import apply_preset, get_preset
from editor.study.mos import Study
from editor.study.stimuli import PAPER_EXPRESSIONS, face_crop


def test_paper_design_from_one_face(tmp_path, sample_face):
    p = argparse.ArgumentParser()
    add_study_parser(p.add_subparsers())
    db = tmp_path / "s.db"
    a = p.parse_args(["study", "create", str(db), "--faces", str(SAMPLE), "--intensities",
                      "0.5,1"])
    assert a.func(a) == 0
    with Study.open(db) as s:
        stim = s.stimuli()
        assert tuple(s.labels) == PAPER_EXPRESSIONS
        assert len(stim) == 5 * 2
        joy = next(x for x in stim if x.label == "joy" and x.intensity == 1.0)
        data = np.frombuffer(s.image_bytes(joy.id), np.uint8)
        img = cv2.cvtColor(cv2.imdecode(data, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        x0, y0, x1, y1 = face_crop(sample_face)
        full = sample_face.render(apply_preset(get_preset("joy"), 1.0), sharp=True)
        assert np.array_equal(img, full[y0:y1, x0:x1])
        # the crop holds the whole face and is much smaller than the photo
        b = sample_face.landmarks.box
        assert x0 < b[0] and y0 < b[1] and x1 > b[2] and y1 > b[3]
        assert img.size < 0.6 * full.size
    bad = p.parse_args(["study", "create", str(tmp_path / "t.db"), "--faces", str(SAMPLE),
                        "--intensities", "3"])
    assert bad.func(bad) == 2 and not (tmp_path / "t.db").exists()
