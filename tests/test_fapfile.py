"""MPEG-4 .fap reader/writer (MPEG4_FAP.md §5.1): round trips, real-file quirks, malformed files."""

from __future__ import annotations

import re

import numpy as np
import pytest

from editor.engine.faps import FAPS
from editor.errors import FapFileError
from editor.formats.blends import blend_expressions, blend_visemes
from editor.formats.fapfile import (
    MAX_FRAMES,
    ExpressionField,
    FapSequence,
    VisemeField,
    fap_info,
    format_fap,
    read_fap,
    write_fap,
)
from editor.formats.keyframes import sequence_from_keyframes


def mask_line(faps: list[int], n: int = 68) -> str:
    return " ".join("1" if i + 1 in faps else "0" for i in range(n))


ANGER_MASK = "0 " * 30 + "1 " * 8 + "0 " * 12 + "1 " * 10 + "0 " * 7 + "0"
# VREng data/bap/anger.fap, first 5 lines (MPEG4_FAP.md §5.1), header count adjusted to 2
VRENG_ANGER = f"""2.1 anger.fap 10 2
{ANGER_MASK}
0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0
{ANGER_MASK}
1 0 -18 0 0 0 0 0 9 0 0 0 0 0 0 0 0 0 0
"""


def random_sequence(rng: np.random.Generator, n: int = 7) -> FapSequence:
    masks = rng.random((n, 68)) < 0.4
    masks[:, :2] = False
    frames = rng.integers(-1200, 1200, (n, 68)).astype(np.float32) * masks
    return FapSequence(frames, masks, fps=12.5, name="random_seq")


# ---------------------------------------------------------------------------- round trips


def assert_same(a: FapSequence, b: FapSequence) -> None:
    assert np.array_equal(a.frames, b.frames)
    assert np.array_equal(a.masks, b.masks)
    assert a.fps == b.fps and a.name == b.name and a.n_frames == b.n_frames
    assert a.visemes == b.visemes and a.expressions == b.expressions


def test_round_trip_sequence_with_changing_masks(tmp_path):
    seq = random_sequence(np.random.default_rng(1))
    back = read_fap(write_fap(seq, tmp_path / "anim.fap"))
    assert_same(seq, back)
    assert back.version == "2.1" and back.notes == []
    assert np.array_equal(back.frame_numbers, np.arange(seq.n_frames))


def test_round_trip_single_frame_and_explicit_zeros(tmp_path):
    v = FAPS.vector({"open_jaw": 300, "raise_l_cornerlip": 150})
    seq = FapSequence.single(v, fps=25, name="joy_like")
    assert seq.masks[0, FAPS["raise_r_cornerlip"].number - 1]  # partner sent as explicit 0
    back = read_fap(write_fap(seq, tmp_path / "one.fap"))
    assert_same(seq, back)
    assert back.frames[0, 2] == 300 and back.masks[0].sum() == 3


def test_writer_format_is_conservative():
    seq = random_sequence(np.random.default_rng(2), 3)
    seq.name = "my animation  v2"
    text = format_fap(seq)
    lines = text.split("\n")
    assert lines[0] == "2.1 my_animation_v2 12.5 3"
    assert text.endswith("\n") and "\t" not in text and "  " not in text and "\r" not in text
    assert "#" not in text and "." not in "".join(lines[1:])
    for k in range(3):
        assert len(lines[1 + 2 * k].split()) == 68
        assert lines[2 + 2 * k].split()[0] == str(k)
    assert format_fap(FapSequence(np.zeros((1, 68)), fps=25.0)).startswith("2.1 fap-studio 25 1\n")


def test_writer_rounds_values_half_away_from_zero():
    seq = FapSequence(FAPS.vector({"open_jaw": 12.5, "lower_t_midlip": -12.5}), fps=25)
    assert format_fap(seq).split("\n")[2] == "0 13 -13"


# ---------------------------------------------------------------------------- real files


def test_vreng_anger_excerpt():
    seq = read_fap(VRENG_ANGER)
    assert (seq.version, seq.name, seq.fps, seq.n_frames) == ("2.1", "anger.fap", 10.0, 2)
    assert seq.used_faps() == list(range(31, 39)) + list(range(51, 61))
    assert not seq.frames[0].any()
    assert seq.frames[1, 31] == -18 and seq.frames[1, 37] == 9  # FAP 32, FAP 38
    assert np.count_nonzero(seq.frames) == 2 and seq.notes == []
    assert seq.duration == pytest.approx(0.2)


def test_xface_style_crlf_trailing_spaces_comment_and_floats():
    m = mask_line([3, 19, 20, 31])
    text = (f"# made by Xface\r\n2.1 C:\\Users\\me\\TempFile 25 2 \r\n{m} \r\n"
            f"0 12.5 128.0 128 -70.4 \r\n{m}\r\n1 -12.5 0 0 0\r\n")
    seq = read_fap(text)
    assert seq.name == "C:\\Users\\me\\TempFile" and seq.fps == 25 and seq.n_frames == 2
    assert list(seq.frames[0, [2, 18, 19, 30]]) == [13, 128, 128, -70]
    assert seq.frames[1, 2] == -13
    assert any("rounded" in n for n in seq.notes) and any("comment" in n for n in seq.notes)


def test_greta_style_69_flags_and_name_with_spaces():
    m = mask_line([19, 20, 21, 22], 69)
    seq = read_fap(f"2.1 AU Interpolation_1160.fap 25 1\n{m}\n0 940 940 200 200\n")
    assert seq.name == "AU Interpolation_1160.fap" and seq.n_frames == 1
    assert list(seq.frames[0, 18:22]) == [940, 940, 200, 200]
    assert any("69" in n for n in seq.notes) and any("spaces" in n for n in seq.notes)
    assert format_fap(seq).split("\n")[0] == "2.1 AU_Interpolation_1160.fap 25 1"


def test_tabs_and_unclamped_negative_u_values():
    m = "\t".join(mask_line([3, 14]).split())
    seq = read_fap(f"2.1\tjag.fap\t10\t1\n{m}\t\n0\t-86\t-1242\n")
    assert list(seq.frames[0, [2, 13]]) == [-86, -1242]  # U FAPs: never clamped
    assert seq.frames[0, 13] < FAPS["thrust_jaw"].range[0]


def test_frames_from_one_and_version_2_0_and_blank_lines(tmp_path):
    m = mask_line([3])
    seq = read_fap(f"2.0 old 25 2\n\n{m}\n1 5\n\n{m}\n2 6\n\n")
    assert list(seq.frame_numbers) == [1, 2] and list(seq.frames[:, 2]) == [5, 6]
    assert any("start at 1" in n for n in seq.notes) and any("2.0" in n for n in seq.notes)
    back = read_fap(write_fap(seq, tmp_path / "old.fap"))
    assert list(back.frame_numbers) == [0, 1] and back.version == "2.1"


def test_fap1_fap2_xface_fields_and_expansion():
    # MPEG4_FAP.md §5.1 constructed example: viseme p/b/m 40/63 with "car"; joy at 63
    text = f"2.1 hl 25 1\n{mask_line([1, 2])}\n0 1 10 40 0 1 63 0 0 0 0\n"
    seq = read_fap(text)
    assert seq.visemes[0] == VisemeField(1, 10, 40, 0)
    assert seq.expressions[0] == ExpressionField(1, 63, 0, 0, 0, 0)
    assert any("Xface" in n for n in seq.notes) and seq.has_high_level
    assert format_fap(seq, high_level="xface") == text  # exact round trip of the fields
    expanded = read_fap(format_fap(seq))  # default: expanded, FAP 1/2 never masked
    assert not expanded.masks[:, :2].any()
    want = np.sign(e := blend_visemes(1, 10, 40) + blend_expressions(1, 63)) * np.floor(
        np.abs(e) + 0.5)
    assert np.array_equal(expanded.frames[0], want.astype(np.float32))
    assert expanded.frames[0, FAPS["raise_l_cornerlip"].number - 1] > 0  # joy is in there


def test_fap1_plain_one_token_form():
    seq = read_fap(f"2.1 p 25 1\n{mask_line([1, 3])}\n0 1 200\n")
    assert seq.frames[0, 0] == 1 and seq.frames[0, 2] == 200 and seq.visemes == [None]
    assert any("plain" in n for n in seq.notes)
    again = read_fap(format_fap(seq))  # plain tokens are dropped by the writer
    assert not again.masks[0, 0] and again.frames[0, 2] == 200


# ---------------------------------------------------------------------------- malformed


M3 = mask_line([3, 4, 5])
BAD = {
    "empty": ("", 1, "empty file"),
    "blank": ("\n  \n", 1, "empty file"),
    "comments only": ("# x\n# y\n", 1, "empty file"),
    "bad version": ("3.1 body 25 1\n", 1, "expected the header"),
    "no header": (f"{M3}\n0 1 2 3\n", 1, "expected the header"),
    "fps zero": ("2.1 x 0 1\n", 1, "frame rate"),
    "fps word": ("2.1 x fast 1\n", 1, "frame rate"),
    "count float": ("2.1 x 25 1.5\n", 1, "frame count"),
    "count huge": ("2.1 x 25 99999999999\n", 1, "frame count"),
    "count zero": ("2.1 x 25 0\n", 1, "frame count"),
    "short data": (f"2.1 x 25 1\n{M3}\n0 1 2\n", 3, "expected 3 values for 3 masked FAPs, got 2"),
    "long data": (f"2.1 x 25 1\n{M3}\n0 1 2 3 4\n", 3, "got 4"),
    "bad number": (f"2.1 x 25 1\n{M3}\n0 1 x2 3\n", 3, "value 2 (FAP 4 lower_t_midlip)"),
    "nan": (f"2.1 x 25 1\n{M3}\n0 1 nan 3\n", 3, "expected a number"),
    "inf": (f"2.1 x 25 1\n{M3}\n0 1 2 -inf\n", 3, "expected a number"),
    "underscore": (f"2.1 x 25 1\n{M3}\n0 1_0 2 3\n", 3, "expected a number"),
    "value too big": (f"2.1 x 25 1\n{M3}\n0 1 2 1e30\n", 3, "|value|"),
    "mask flag 2": (f"2.1 x 25 1\n{M3.replace('1', '2', 1)}\n0 1 2 3\n", 2, "mask flag 3 is '2'"),
    "mask short": ("2.1 x 25 1\n0 1 0\n0 5\n", 2, "expected a mask line of 68 flags"),
    "missing mask": (f"2.1 x 25 2\n{M3}\n0 1 2 3\n1 1 2 3\n{M3}\n", 4, "mask line"),
    "truncated": (f"2.1 x 25 3\n{M3}\n0 1 2 3\n", 4, "unexpected end of file"),
    "truncated mid": (f"2.1 x 25 2\n{M3}\n0 1 2 3\n{M3}\n", 5, "declares 2 frames"),
    "extra data": (f"2.1 x 25 1\n{M3}\n0 1 2 3\n{M3}\n1 1 2 3\n", 4, "expected the end"),
    "frame order": (f"2.1 x 25 2\n{M3}\n0 1 2 3\n{M3}\n2 1 2 3\n", 5, "out of order, expected 1"),
    "frame start": (f"2.1 x 25 1\n{M3}\n5 1 2 3\n", 3, "out of order, expected 0"),
    "frame word": (f"2.1 x 25 1\n{M3}\nA 1 2 3\n", 3, "frame number"),
    "viseme range": (f"2.1 x 25 1\n{mask_line([1])}\n0 20 0 0 0\n", 3, "select1 must be"),
    "nul": ("2.1 x 25 1\n" + M3 + "\n0 1\x00 2 3\n", 3, "NUL"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_malformed_files_name_the_line(case):
    text, line, what = BAD[case]
    with pytest.raises(FapFileError) as err:
        read_fap(text, label="anim.fap")
    msg = str(err.value)
    assert msg.startswith(f"anim.fap line {line}: "), msg
    assert what in msg, msg


def test_message_names_the_file_and_expected_count(tmp_path):
    masks = mask_line(list(range(31, 39)) + list(range(51, 61)))
    lines = ["2.1 a 25 3", masks, "0" + " 0" * 18, masks, "1" + " 0" * 18, masks, "2" + " 0" * 17]
    p = tmp_path / "anim.fap"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(FapFileError, match=re.escape(
            "anim.fap line 7: expected 18 values for 18 masked FAPs, got 17")):
        read_fap(p)


def test_binary_garbage_and_non_utf8(tmp_path):
    rng = np.random.default_rng(0)
    garbage = b"2.1 x 25 1\n" + bytes(rng.integers(0, 256, 4000, dtype=np.uint8))
    with pytest.raises(FapFileError, match=r"line \d+: "):
        read_fap(garbage)
    with pytest.raises(FapFileError, match=r"<bytes> line 2: byte 0xff is not UTF-8"):
        read_fap(b"2.1 x 25 1\n\xff\xfe 0 0\n")
    p = tmp_path / "img.fap"
    p.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR")
    with pytest.raises(FapFileError, match=r"img.fap line 3: binary data"):
        read_fap(p)


def test_huge_declared_count_is_not_allocated():
    """A header declaring a million frames is not trusted: memory follows the data read."""
    import tracemalloc

    text = f"2.1 x 25 {MAX_FRAMES}\n{M3}\n0 1 2 3\n"
    tracemalloc.start()
    try:
        with pytest.raises(FapFileError, match=r"line 4: unexpected end of file.*1000000 frames"):
            read_fap(text)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 4 * 68 * MAX_FRAMES // 100  # far below the 272 MB of a preallocated array


def test_missing_file(tmp_path):
    with pytest.raises(FapFileError, match="nope.fap: cannot read"):
        read_fap(tmp_path / "nope.fap")


def test_write_error_is_a_fap_file_error(tmp_path, monkeypatch):
    import errno

    from editor import safeio

    seq = FapSequence(np.zeros((1, 68)))
    (tmp_path / "a_file").write_text("x")
    with pytest.raises(FapFileError, match="cannot write"):  # the folder is a file
        write_fap(seq, tmp_path / "a_file" / "x.fap")
    old = write_fap(FapSequence(np.ones((1, 68))), tmp_path / "x.fap").read_bytes()

    def full(fh, data):
        fh.write(data[: len(data) // 2])
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(safeio, "_write_all", full)  # the disk fills while writing
    with pytest.raises(FapFileError, match="x.fap: cannot write .No space left"):
        write_fap(seq, tmp_path / "x.fap")
    assert (tmp_path / "x.fap").read_bytes() == old  # the old file is intact
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "x.fap"]  # no temp file


# ---------------------------------------------------------------------------- helpers


def test_sequence_from_keyframes_neutral_joy_neutral():
    joy = FAPS.vector({"open_jaw": 100, "raise_l_cornerlip": 150, "raise_r_cornerlip": 150})
    zero = np.zeros(68, np.float32)
    seq = sequence_from_keyframes([(0.0, zero), (1.0, joy), (2.0, zero)], fps=25)
    assert seq.n_frames == 51 and seq.fps == 25
    assert np.array_equal(seq.frames[25], joy) and not seq.frames[[0, 50]].any()
    assert seq.frames[12, 2] == 48  # 100 * 12/25
    assert seq.masks.all(axis=0)[[2, 11, 12]].all() and seq.masks[:, :2].sum() == 0
    eased = sequence_from_keyframes([(0.0, zero), (1.0, joy)], 25, "smoothstep")
    u = 5 / 25
    assert eased.frames[5, 2] == round(100 * u * u * (3 - 2 * u))
    late = sequence_from_keyframes([(0.4, joy)], 10)
    assert late.n_frames == 5 and np.array_equal(late.frames[0], joy)  # first key held


@pytest.mark.parametrize("kwargs", [
    {"keys": [(0.0, np.zeros(68)), (0.0, np.zeros(68))]},
    {"keys": [], "fps": 25},
    {"keys": [(0.0, np.zeros(68))], "interpolation": "cubic"},
    {"keys": [(0.0, np.zeros(67))]},
    {"keys": [(0.0, np.ones(68))]},  # FAP 1/2 non-zero
    {"keys": [(0.0, np.zeros(68))], "fps": 0},
])
def test_sequence_from_keyframes_rejects_bad_input(kwargs):
    with pytest.raises(ValueError):
        sequence_from_keyframes(**kwargs)


def test_fap_info_lists_what_matters():
    info = fap_info(read_fap(VRENG_ANGER))
    for text in ("version:  2.1", "name:     anger.fap", "fps:      10", "frames:   2",
                 "duration: 0.200 s", "FAPs used (18)", "32 raise_r_i_eyebrow", "-18"):
        assert text in info
    hl = fap_info(read_fap(f"2.1 hl 25 1\n{mask_line([2])}\n0 1 63 0 0 0 0\n"))
    assert "expression fields in 1 frame(s)" in hl and "Xface" in hl


def test_sequence_validation():
    with pytest.raises(ValueError):
        FapSequence(np.zeros((2, 67)))
    with pytest.raises(ValueError):
        FapSequence(np.full((1, 68), np.nan))
    with pytest.raises(ValueError):
        FapSequence(np.zeros((1, 68)), fps=-1)
    with pytest.raises(ValueError):
        VisemeField(15, 0, 0)
    seq = FapSequence(np.ones((2, 68)), masks=np.zeros((2, 68), bool))
    assert not seq.frames.any()  # unmasked values are 0


def test_writer_refuses_a_file_the_readers_would_refuse(monkeypatch, tmp_path, cli):
    """``fap export --frames N`` never writes a .fap larger than the readers accept (it wrote a
    290 MB file that ``fap info`` and ``animate`` then refused); the size is counted exactly."""
    from editor.formats import fapfile
    from editor.formats.presets import apply_preset

    seq = fapfile.FapSequence.single(apply_preset("joy"), frames=100, name="joy")
    text = fapfile.format_fap(seq)
    monkeypatch.setattr(fapfile, "MAX_FILE_BYTES", len(text.encode()))
    assert fapfile.format_fap(seq) == text  # exactly at the limit: written
    monkeypatch.setattr(fapfile, "MAX_FILE_BYTES", len(text.encode()) - 1)
    with pytest.raises(fapfile.FapFileError, match="readers accept at most"):
        fapfile.format_fap(seq)
    out = tmp_path / "big.fap"
    r = cli("fap", "export", "--preset", "joy", "--frames", "100", "-o", out)
    assert r.returncode == 2 and "readers accept at most" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not out.exists()
