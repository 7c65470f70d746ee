"""Shared CLI pieces: the tqdm progress bar driven by ``progress(done, total)`` callbacks."""

from __future__ import annotations

from editor.cli.util import ProgressBar


def test_progress_bar_follows_done_and_a_growing_total(capsys):
    with ProgressBar("track") as bar:
        assert bar(1, 3) is True
        assert bar(3, 5) is True  # the total grew (an estimate)
        assert (bar.bar.n, bar.bar.total) == (3, 5)
        assert bar(5, 5)
    err = capsys.readouterr().err
    assert "track" in err and "5/5" in err and err.endswith("\n")
    assert capsys.readouterr().out == ""


def test_quiet_progress_bar_prints_nothing(capsys):
    with ProgressBar("render", quiet=True) as bar:
        for i in range(1, 4):
            assert bar(i, 3)
    assert capsys.readouterr().err == ""


def test_no_bar_before_the_first_progress(capsys):
    with ProgressBar("track"):
        pass  # e.g. the video could not be opened
    assert capsys.readouterr().err == ""
