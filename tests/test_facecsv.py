"""Live Link Face CSV and AU CSV: readers refuse malformed files with one line naming the row
and column (CLI exit 2, nothing written); writers and readers round-trip; the CLI converts,
renders ``--au`` and animates a CSV."""

from __future__ import annotations

import numpy as np
import pytest

from editor.errors import CsvFormatError
from editor.formats.arkit import arkit_table
from editor.formats.facecsv import read_animation, read_au_csv, read_live_link, write_animation
from editor.formats.fapfile import FapSequence


def live_link(rows: list[tuple[str, dict[str, float]]], rotations: bool = True) -> str:
    t = arkit_table()
    names = list(t.csv_names) + (list(t.rotations) if rotations else [])
    out = ["Timecode,BlendShapeCount," + ",".join(names)]
    for tc, vals in rows:
        cells = [f"{vals.get(n, 0.0):.4f}" for n in names]
        out.append(f"{tc},{len(names)}," + ",".join(cells))
    return "\n".join(out) + "\n"


def au_csv(rows: list[str], header: str = "frame, face_id, timestamp, confidence, success, "
           "AU01_r, AU12_r, AU45_r, AU12_c") -> str:
    return header + "\n" + "\n".join(rows) + "\n"


SMILE = [(f"12:00:00:{k:02d}.000", {"MouthSmileLeft": k / 10, "MouthSmileRight": k / 10,
                                     "JawOpen": 0.5, "HeadRoll": 0.1}) for k in range(11)]


def test_live_link_reads_timecodes_weights_and_rotations(tmp_path):
    p = tmp_path / "cap.csv"
    p.write_text(live_link(SMILE))
    cap = read_live_link(p, fps=30)
    assert np.allclose(cap.times, np.arange(11) / 30)
    t = arkit_table()
    assert cap.weights[10, t.names.index("mouthSmileLeft")] == pytest.approx(1.0)
    assert cap.rotations[0, t.rotations.index("HeadRoll")] == pytest.approx(0.1)
    seq, kind, _ = read_animation(p, fps=30)
    assert kind == "arkit" and seq.n_frames == 11
    assert seq.frames[10, 59 - 1] > 300 and seq.frames[0, 50 - 1] == pytest.approx(10000)


def test_live_link_infers_the_frame_rate_and_says_so(tmp_path):
    p = tmp_path / "cap.csv"
    rows = [(f"00:00:{s:02d}:{f:02d}.500", {}) for s in range(2) for f in range(60)]
    p.write_text(live_link(rows, rotations=False))
    cap = read_live_link(p)
    assert cap.fps == 60 and "60 fps inferred" in cap.notes[0]
    assert cap.times[-1] == pytest.approx(119 / 60)
    assert not cap.has_rotations


@pytest.mark.parametrize(("mutate", "where", "what"), [
    (lambda s: s.replace("EyeBlinkLeft", "EyeBlinkLeftt", 1), "line 1, column 3",
     "unknown column"),
    (lambda s: s.replace("Timecode,", "Time,", 1), "line 1", "Timecode,BlendShapeCount"),
    (lambda s: s.replace(",EyeBlinkLeft", "", 1), "line 1", "EyeBlinkLeft"),
    (lambda s: s.replace("0.5000", "abc", 1), "line 2, column JawOpen", "'abc'"),
    (lambda s: s.replace("0.5000", "1.7", 1), "line 2, column JawOpen", "0 to 1"),
    (lambda s: s.replace(",0.5000", "", 1), "line 2", "expected 63 comma-separated values"),
    (lambda s: s.replace("12:00:00:05.000", "12:00:00:03.000"), "line 7, column Timecode",
     "not after the previous row's 12:00:00:04.000"),
    (lambda s: s.replace("12:00:00:05.000", "12:00:00:05"), None, None),  # no fraction: fine
    (lambda s: s.replace("12:00:00:05.000", "12:00:05.000"), "line 7, column Timecode",
     "HH:MM:SS:FF"),
    (lambda s: s.replace(",61,", ",x1,", 1), "line 2, column BlendShapeCount", "whole number"),
    (lambda s: s.replace(",61,", ",51,", 1), None, None),  # exporters disagree: noted only
    (lambda s: s.replace("0.1000", "nan", 1), "line 2, column HeadRoll", "'nan'"),
])
def test_live_link_reader_refuses_malformed_files_with_one_line(tmp_path, mutate, where, what):
    p = tmp_path / "bad.csv"
    p.write_text(mutate(live_link(SMILE)))
    if where is None:
        read_live_link(p, fps=30)
        return
    with pytest.raises(CsvFormatError) as e:
        read_live_link(p, fps=30)
    msg = str(e.value)
    assert msg.startswith(f"bad.csv {where}") and what in msg and "\n" not in msg


def test_live_link_writes_the_apps_column_order_and_reads_degrees(tmp_path):
    from editor.formats.facs import aus_to_faps

    f = aus_to_faps({"L12": 1.0})
    f[49 - 1] = 10000  # head yaw 0.1 rad
    write_animation(FapSequence(f[None].astype(np.float32), fps=60), tmp_path / "o.csv", "arkit")
    header = (tmp_path / "o.csv").read_text().splitlines()[0]
    assert ",JawForward,JawRight,JawLeft,JawOpen," in header
    assert ",MouthPucker,MouthRight,MouthLeft,MouthSmileLeft," in header
    assert header.endswith(",HeadYaw,HeadPitch,HeadRoll,LeftEyeYaw,LeftEyePitch,LeftEyeRoll,"
                           "RightEyeYaw,RightEyePitch,RightEyeRoll")
    cap = read_live_link(tmp_path / "o.csv")
    t = arkit_table()
    assert cap.weights[0, t.names.index("mouthSmileLeft")] > 0.9
    assert cap.weights[0, t.names.index("mouthSmileRight")] < 0.05
    p = tmp_path / "deg.csv"
    p.write_text(live_link([("00:00:00:00.000", {"HeadYaw": 20.0})]))
    cap = read_live_link(p, fps=30)
    assert cap.rotations[0, 0] == pytest.approx(np.radians(20)) and "degrees" in cap.notes[0]


def test_live_link_frame_beyond_the_given_rate_is_refused(tmp_path):
    p = tmp_path / "cap.csv"
    p.write_text(live_link([("00:00:00:40.000", {})]))
    with pytest.raises(CsvFormatError, match="line 2, column Timecode: frame 40 does not "
                       "exist at 30 fps"):
        read_live_link(p, fps=30)


def test_au_csv_reads_openface_columns(tmp_path):
    p = tmp_path / "of.csv"
    p.write_text(au_csv(["1, 0, 0.000, 0.98, 1, 1.0, 5.0, 0.0, 1",
                         "2, 0, 0.040, 0.98, 1, 0.0, 2.5, 4.0, 1"]))
    cap = read_au_csv(p)
    assert cap.fps == 25 and np.allclose(cap.times, [0, 0.04])
    numbers = [a.number for a in __import__("editor.formats.facs", fromlist=["x"])
               .au_table().aus]
    assert cap.values[0, numbers.index(12)] == 1.0 and cap.values[1, numbers.index(43)] == 0.8
    assert cap.values[0, numbers.index(1)] == pytest.approx(0.2)  # 1 of 5 = FACS A
    assert any("AUxx_c" in n for n in cap.notes)


@pytest.mark.parametrize(("rows", "header", "where", "what"), [
    (["1, 0, 0.0, 1, 1, 1, 2, 3, 1"], "frame, face_id, confidence, AU01_r, AU12_r", "line 1",
     "'timestamp'"),
    (["1, 0, 0.0, 1, 1, 1, 2, 3, 1"], "frame, timestamp, AU11_r, gaze_0_x", "line 1",
     "no AUxx_r"),
    (["1, 0, 0.0, 1, 1, x, 2, 3, 1"], None, "line 2, column AU01_r", "'x'"),
    (["1, 0, 0.0, 1, 1, 6, 2, 3, 1"], None, "line 2, column AU01_r", "0 to 5"),
    (["1, 0, 0.0, 1, 1, 1, 2, 3"], None, "line 2", "expected 9 comma-separated values"),
    (["1, 0, 0.1, 1, 1, 1, 2, 3, 1", "2, 0, 0.1, 1, 1, 1, 2, 3, 1"], None,
     "line 3, column timestamp", "not after"),
    (["2, 0, 0.0, 1, 1, 1, 2, 3, 1", "1, 0, 0.1, 1, 1, 1, 2, 3, 1"], None,
     "line 3, column frame", "not after"),
    (["1, 0, 0.0, 1, 1, 1, 2, 3, 1"], "frame, timestamp, AU01_r, AU01_r, AU12_r, a, b, c, d",
     "line 1, column 4", "twice"),
])
def test_au_csv_reader_refuses_malformed_files_with_one_line(tmp_path, rows, header, where,
                                                              what):
    p = tmp_path / "bad.csv"
    p.write_text(au_csv(rows) if header is None else au_csv(rows, header))
    with pytest.raises(CsvFormatError) as e:
        read_au_csv(p)
    msg = str(e.value)
    assert msg.startswith(f"bad.csv {where}") and what in msg and "\n" not in msg


@pytest.mark.parametrize("kind", ["arkit", "au", "fap"])
def test_writers_round_trip_through_their_readers(tmp_path, kind):
    from editor.formats.facs import aus_to_faps

    frames = np.stack([aus_to_faps({"12": x, "26": 1 - x, "43": x}) for x in
                       np.linspace(0, 1, 26)]).astype(np.float32)
    seq = FapSequence(frames, fps=25)
    out = tmp_path / ("a.fap" if kind == "fap" else f"{kind}.csv")
    write_animation(seq, out, kind)
    back, got, _ = read_animation(out)
    assert got == kind and back.n_frames == 26 and back.fps == 25
    # FAPs made of table AUs come back within a few FAPU (bounded fit's ridge and rounding)
    assert np.abs(back.frames - frames).max() < 25


def test_au_csv_keeps_one_intensity_per_au(tmp_path):
    """OpenFace-style files have no sides: a wink comes back as half a closure of both eyes
    (the loss the README states), while ARKit keeps it."""
    from editor.formats.facs import aus_to_faps

    seq = FapSequence(aus_to_faps({"L46": 1.0})[None].astype(np.float32), fps=25)
    for kind, left, right in (("au", 480, 480), ("arkit", 960, 0)):
        write_animation(seq, tmp_path / f"{kind}.csv", kind)
        back = read_animation(tmp_path / f"{kind}.csv")[0].frames[0]
        assert back[18] == pytest.approx(left, abs=40) and back[19] == pytest.approx(right,
                                                                                     abs=40)


def test_cli_convert_render_and_animate_csv(cli, tmp_path):
    src = tmp_path / "cap.csv"
    src.write_text(live_link(SMILE))
    r = cli("convert", src, tmp_path / "a.fap", "--fps", "30")
    assert r.returncode == 0, r.stderr
    assert "Live Link Face CSV -> .fap: 11 frames at 30 fps" in r.stderr
    r = cli("convert", tmp_path / "a.fap", tmp_path / "au.csv", "--to", "au")
    assert r.returncode == 0 and (tmp_path / "au.csv").read_text().startswith("frame, face_id")
    r = cli("convert", tmp_path / "a.fap", tmp_path / "x.csv")
    assert r.returncode == 2 and "--to arkit" in r.stderr and not (tmp_path / "x.csv").exists()
    bad = tmp_path / "bad.csv"
    bad.write_text(live_link(SMILE).replace("0.5000", "oops", 1))
    r = cli("convert", bad, tmp_path / "b.fap")
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert "bad.csv line 2, column JawOpen" in r.stderr and not (tmp_path / "b.fap").exists()
    frames = tmp_path / "frames"
    r = cli("animate", "sample", tmp_path / "au.csv", "-o", frames, "-q")
    assert r.returncode == 0, r.stderr
    assert len(list(frames.glob("*.png"))) == 11


def test_cli_render_au_moves_the_mouth_corners_and_lids(cli, tmp_path, sample_face):
    from editor.engine.imageio import load_image

    plain, smile = tmp_path / "n.png", tmp_path / "s.png"
    assert cli("render", "sample", "-o", plain).returncode == 0
    r = cli("render", "sample", "--au", "AU12=0.8", "--au", "6=C", "-o", smile)
    assert r.returncode == 0, r.stderr
    diff = np.abs(load_image(smile).astype(int) - load_image(plain).astype(int)).sum(axis=2)
    face = sample_face
    for fdp in ("8.3", "8.4", "3.3", "3.4"):  # mouth corners (AU12), lower lids (AU6)
        x, y = face.vertices[face.fdp[fdp]].astype(int)
        assert (diff[y - 6:y + 7, x - 6:x + 7] > 30).sum() > 10, fdp
    x, y = face.vertices[face.fdp["4.1"]].astype(int)
    assert (diff[y - 12:y - 4, x - 6:x + 7] > 30).sum() == 0  # above the brow: untouched
    r = cli("render", "sample", "--au", "12=F", "-o", tmp_path / "x.png")
    assert r.returncode == 2 and "A-E" in r.stderr and not (tmp_path / "x.png").exists()


def test_cli_convert_resamples_a_fap_file(cli, tmp_path):
    from editor.formats.fapfile import read_fap, write_fap

    frames = np.zeros((26, 68), np.float32)
    frames[:, 2] = np.linspace(0, 500, 26)  # open_jaw ramps over one second at 25 fps
    write_fap(FapSequence(frames, fps=25), tmp_path / "a.fap")
    r = cli("convert", tmp_path / "a.fap", tmp_path / "b.fap", "--fps", "50")
    assert r.returncode == 0, r.stderr
    b = read_fap(tmp_path / "b.fap")
    assert b.fps == 50 and b.n_frames == 51
    assert b.frames[1, 2] == 10 and b.frames[50, 2] == 500  # halfway between 0 and 20
