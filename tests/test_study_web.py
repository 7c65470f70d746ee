"""Remote raters (editor.study.remote, .web, .qc and ``study serve/invite/revoke/qc``): tokens,
server-side validation, P.808-style QC, a killed server, and a real browser."""

from __future__ import annotations

import os
import re
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import httpx2 as httpx
import pytest
from starlette.testclient import TestClient

from editor.study.mos import CANNOT_TELL, Study
from editor.study.qc import QcItemSpec, add_qc_items, qc_image, qc_items, rater_qc, trap_specs
from editor.study.remote import invite
from editor.study.stimuli import create_from_renders
from editor.study.web import create_app
from tests.test_mos import LABELS, _renders

REPO = Path(__file__).resolve().parents[1]
TABLES = ("raters", "rater_order", "answers", "web_plan", "qc_answers", "web_tokens")


def _make(path: Path, raters: int = 2) -> list:
    """6 stimuli (break after every 3 trials), 1 training, 1 gold and 1 trapping trial."""
    with create_from_renders(path, "pilot", LABELS, _renders(), break_every=3) as st:
        img = st.image_bytes(1)
        add_qc_items(st, [QcItemSpec("training", "Ann", ("joy",), 1, 5, "practice", img),
                          QcItemSpec("gold", "Ann", (CANNOT_TELL,), 3, 5, "unchanged", img),
                          *trap_specs(st, 1, seed=3)])
        return invite(st, raters)


@pytest.fixture()
def web(tmp_path: Path):
    path = tmp_path / "study.db"
    return path, _make(path)


def _snapshot(path: Path) -> dict[str, list]:
    con = sqlite3.connect(path)
    try:
        return {t: con.execute(f"SELECT * FROM {t} ORDER BY 1, 2").fetchall() for t in TABLES}
    finally:
        con.close()


def _n_answered(path: Path, rater: str) -> int:
    """Committed answers of a rater: study stimuli plus QC trials."""
    con = sqlite3.connect(path)
    try:
        return sum(con.execute(f"SELECT COUNT(*) FROM {t} WHERE rater=?", (rater,)).fetchone()[0]
                   for t in ("answers", "qc_answers"))
    finally:
        con.close()


def _post(c, token: str, **answer) -> httpx.Response:
    return c.post(f"/r/{token}/api/answer", json=answer)


def _good(state: dict, label: str = "joy", nat: int = 4) -> dict:
    return {"position": state["trial"]["position"], "label": label, "naturalness": nat,
            "response_ms": 812.5}


def test_every_request_needs_a_valid_token(web, cli) -> None:
    path, (a, b) = web
    before = _snapshot(path)
    with TestClient(create_app(path)) as c:
        for url in ("/", "/r/", "/r//api/state", "/index.html", "/r/nope/", "/r/nope/app.js",
                    f"/r/{a.token[:-1]}x/api/state", f"/r/{a.token}x/img/0"):
            assert c.get(url).status_code == 403, url
        assert c.post("/r/nope/api/answer", json={"position": 0, "label": "joy",
                                                  "naturalness": 3, "response_ms": 1}
                      ).status_code == 403
        assert _snapshot(path) == before  # nothing written by refused requests
        res = cli("study", "revoke", path, b.rater)
        assert res.returncode == 0 and b.rater in res.stdout
        before = _snapshot(path)
        assert before["web_tokens"][1][3] is not None  # revoked_at
        for url in (f"/r/{b.token}/", f"/r/{b.token}/api/state", f"/r/{b.token}/img/0"):
            assert c.get(url).status_code == 403, url
        assert _snapshot(path) == before
        slash = c.get(f"/r/{a.token}", follow_redirects=False)
        assert slash.status_code == 308 and slash.headers["location"] == f"{a.token}/"
        page = c.get(f"/r/{a.token}/")  # a valid token still works, from a running server
        assert page.status_code == 200 and "app.js" in page.text
        assert page.headers["referrer-policy"] == "no-referrer"
        assert c.get(f"/r/{a.token}/app.js").status_code == 200
        assert c.get(f"/r/{a.token}/api/state").json()["done"] == 0
    assert cli("study", "revoke", path, "web-999").returncode == 2


def test_a_study_without_invites_refuses_everyone(tmp_path: Path) -> None:
    path = tmp_path / "s.db"
    create_from_renders(path, "pilot", LABELS, _renders()).close()
    with TestClient(create_app(path)) as c:
        assert c.get("/r/AAAAAAAAAAAAAAAAAAAAAA/api/state").status_code == 403
    with Study.open(path) as st:
        assert st.raters() == []


def test_tokens_are_random_and_stored_hashed(web, cli) -> None:
    path, invites = web
    res = cli("study", "invite", path, "--raters", "3", "--base-url", "https://rate.example.org/")
    assert res.returncode == 0, res.stderr
    urls = re.findall(r"https://rate\.example\.org/r/([A-Za-z0-9_-]+)/", res.stdout)
    tokens = [*urls, *(i.token for i in invites)]
    assert len(urls) == 3 and len(set(tokens)) == 5 and all(len(t) >= 22 for t in tokens)
    raw = path.read_bytes() + (Path(f"{path}-wal").read_bytes()
                               if Path(f"{path}-wal").exists() else b"")
    assert not any(t.encode() in raw for t in tokens)  # only SHA-256 hashes are stored
    assert cli("study", "invite", path, "--raters", "0").returncode == 2


def test_answers_are_validated_server_side(web) -> None:
    path, (a, _) = web
    with TestClient(create_app(path)) as c:
        state = c.get(f"/r/{a.token}/api/state").json()
        before = _snapshot(path)
        good = _good(state)
        bad = [{**good, "label": "neutral"}, {**good, "label": 1}, {**good, "naturalness": 0},
               {**good, "naturalness": 6}, {**good, "naturalness": "4"},
               {**good, "naturalness": 4.5}, {**good, "naturalness": True},
               {**good, "response_ms": -1}, {**good, "response_ms": 1e12},
               {**good, "position": -1}, {**good, "extra": 1},
               {k: v for k, v in good.items() if k != "label"}, [good], "joy"]
        for body in bad:
            r = c.post(f"/r/{a.token}/api/answer", json=body)
            assert r.status_code == 400, (body, r.text)
        for raw in (b"{", b"NaN", b'{"position": 0, "label": "joy", "naturalness": 4, '
                    b'"response_ms": NaN}', "é".encode("latin-1")):
            assert c.post(f"/r/{a.token}/api/answer", content=raw).status_code == 400, raw
        assert c.post(f"/r/{a.token}/api/answer", content=b" " * 5000).status_code == 413
        r = _post(c, a.token, **{**good, "position": good["position"] + 1})
        assert r.status_code == 409 and "not the current" in r.json()["error"]
        assert c.get(f"/r/{a.token}/img/1").status_code == 404  # later images stay hidden
        assert c.get(f"/r/{a.token}/api/answer").status_code == 405
        assert _snapshot(path) == before
        ok = _post(c, a.token, **good)
        assert ok.status_code == 200 and ok.json()["done"] == 1
        after = _snapshot(path)
        replay = _post(c, a.token, **good)  # the same answer again: refused, nothing written
        assert replay.status_code == 409 and "already answered" in replay.json()["error"]
        assert _post(c, a.token, **{**good, "label": "fear"}).status_code == 409
        assert _snapshot(path) == after


def test_rate_limit_per_token(web) -> None:
    path, (a, b) = web
    with TestClient(create_app(path, rate_limit="5/minute")) as c:
        codes = [c.get(f"/r/{a.token}/api/state").status_code for _ in range(7)]
        assert codes == [200] * 5 + [429] * 2
        assert c.get(f"/r/{b.token}/api/state").status_code == 200  # another token: own budget


def test_a_web_session_fills_the_same_store_with_qc(web, cli) -> None:
    path, (a, b) = web
    with Study.open(path) as st:
        items = {i.kind: i for i in qc_items(st)}
    trap = items["trap"]
    with TestClient(create_app(path)) as c:
        for inv, fail_trap in ((a, False), (b, True)):
            state = c.get(f"/r/{inv.token}/api/state").json()
            assert state["total"] == 9 and state["training"] == 1
            assert "joy" not in str(state["trial"])  # the intended answer never leaks
            kinds, breaks = [], 0
            while state["trial"]:
                pos = state["trial"]["position"]
                img = c.get(f"/r/{inv.token}/img/{pos}")
                assert img.status_code == 200 and img.headers["content-type"] == "image/png"
                # which item is this? the store knows; the page does not
                con = sqlite3.connect(path)
                row = con.execute("SELECT item FROM web_plan WHERE rater=? AND position=?",
                                  (inv.rater, pos)).fetchone()
                con.close()
                kind = next((k for k, i in items.items() if i.id == row[0]), "stimulus")
                kinds.append(kind)
                answer = _good(state)
                if kind == "gold":
                    answer["label"] = CANNOT_TELL
                elif kind == "trap":
                    answer["label"] = trap.accept[0]
                    answer["naturalness"] = trap.nat_min % 5 + 1 if fail_trap else trap.nat_min
                r = _post(c, inv.token, **answer)
                assert r.status_code == 200, r.text
                if kind == "training":
                    assert r.json()["feedback"] == {"correct": True, "intended": "joy"}
                state = r.json()
                breaks += state["break_due"]
            assert kinds[0] == "training" and kinds[1] == "stimulus"
            assert sorted(kinds) == sorted(["training", "gold", "trap", *["stimulus"] * 6])
            assert breaks == 2 and state["done"] == 9
    with Study.open(path) as st:
        assert {r: len(st.answers(r)) for r in st.raters()} == {a.rater: 6, b.rater: 6}
        qc = {r.rater: r for r in rater_qc(st)}
    assert not qc[a.rater].excluded and qc[b.rater].excluded
    assert "trapping" in qc[b.rater].reasons
    report = cli("study", "report", path)
    assert report.returncode == 0, report.stderr
    out = report.stdout
    assert "6 answers (MOS without the 1 raters excluded by QC)" in out
    assert re.search(rf"{b.rater}\s+1/1\s+1/1\s+0/1\s+EXCLUDED: failed 1 of 1 trapping", out)
    assert re.search(rf"{a.rater}\s+1/1\s+1/1\s+1/1\s+kept", out)
    assert "Rule: a rater with QC trials is excluded" in out


@pytest.mark.gui
def test_results_window_states_qc(web, qtbot) -> None:
    from editor.ui.mos_results import ResultsWindow

    path, (a, _) = web
    with TestClient(create_app(path)) as c:
        state = c.get(f"/r/{a.token}/api/state").json()
        while state["trial"]:  # "joy" everywhere: the gold trial wants "cannot tell"
            state = _post(c, a.token, **_good(state, nat=1)).json()
    win = ResultsWindow(path)
    qtbot.addWidget(win)
    text = win.summary_label.text()
    assert "1 excluded from MOS" in text and a.rater in text and "0 answers" in text


def test_qc_cli_adds_traps_and_needs_faces_for_gold(tmp_path: Path, cli) -> None:
    path = tmp_path / "s.db"
    create_from_renders(path, "pilot", LABELS, _renders()).close()
    res = cli("study", "qc", path, "--traps", "3")
    assert res.returncode == 0 and "0 training, 0 gold, 3 trapping" in res.stdout
    with Study.open(path) as st:
        traps = qc_items(st)
    assert [t.kind for t in traps] == ["trap"] * 3
    assert all(t.nat_min == t.nat_max and len(t.accept) == 1 for t in traps)
    assert cli("study", "qc", path, "--traps", "-1").returncode == 2


# ---------------------------------------------------------------- a real server process
def _start_server(path: Path) -> tuple[subprocess.Popen, str]:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-m", "editor.cli", "study", "serve", str(path),
                             "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)
    line = proc.stdout.readline() if proc.stdout else ""
    m = re.search(r"(http://127\.0\.0\.1:\d+)/r/TOKEN/ to 2 invited raters", line)
    if not m:
        proc.kill()
        err = proc.stderr.read() if proc.stderr else ""
        raise AssertionError(f"server did not start: {line!r} {err}")
    base = m.group(1)
    for _ in range(100):  # the socket is bound before the line; wait for the app's startup
        try:
            if httpx.get(f"{base}/", timeout=1).status_code == 403:
                break
        except httpx.TransportError:
            time.sleep(0.05)
    return proc, base


@pytest.fixture()
def server(web):
    path, invites = web
    procs: list[subprocess.Popen] = []

    def start() -> str:
        proc, base = _start_server(path)
        procs.append(proc)
        return base

    yield path, invites, start, procs
    for p in procs:
        if p.poll() is None:
            p.kill()
        p.wait(10)


def test_killed_server_loses_no_answer(server) -> None:
    """kill -9 while a rater keeps answering: every acknowledged answer is stored (and at most
    the one in flight besides); a new server resumes the rater right after the last one."""
    import threading

    path, (a, _), start, procs = server
    base = start()
    acked: list[int] = []

    def rate() -> None:
        with httpx.Client(base_url=f"{base}/r/{a.token}/") as c:
            state = c.get("api/state").json()
            try:
                while state["trial"] and len(acked) < 8:
                    r = c.post("api/answer", json=_good(state))
                    assert r.status_code == 200
                    acked.append(r.json()["done"])
                    state = r.json()
            except httpx.TransportError:
                pass  # the server died mid-request

    rater = threading.Thread(target=rate)
    rater.start()
    deadline = time.monotonic() + 20
    while len(acked) < 4 and rater.is_alive() and time.monotonic() < deadline:
        time.sleep(0.001)
    assert len(acked) >= 4
    os.kill(procs[0].pid, signal.SIGKILL)  # kill -9 mid-session
    procs[0].wait(10)
    rater.join(10)
    Study.open(path).close()  # opens cleanly (quick_check)
    stored = _n_answered(path, a.rater)
    assert len(acked) in (stored, stored - 1) and stored >= 4
    base = start()  # a new server resumes the rater after the last stored answer
    with httpx.Client(base_url=f"{base}/r/{a.token}/") as c:
        state = c.get("api/state").json()
        assert state["done"] == stored and state["trial"]["position"] == stored
        assert c.post("api/answer", json=_good(state)).json()["done"] == stored + 1


def test_serve_stops_on_ctrl_c(server) -> None:
    path, (a, _), start, procs = server
    base = start()
    assert httpx.get(f"{base}/r/{a.token}/api/state").status_code == 200
    procs[0].send_signal(signal.SIGINT)  # uvicorn shuts down, then 130 as every command
    assert procs[0].wait(10) == 130
    err = procs[0].stderr.read() if procs[0].stderr else ""
    assert "Traceback" not in err, err


def test_serve_bad_input_is_one_line(tmp_path: Path, cli) -> None:
    junk = tmp_path / "junk.db"
    junk.write_bytes(b"not a study")
    res = cli("study", "serve", junk, "--port", "0")
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "not an SQLite" in res.stderr
    path = tmp_path / "s.db"
    create_from_renders(path, "pilot", LABELS, _renders()).close()
    res = cli("study", "serve", path, "--rate-limit", "lots")
    assert res.returncode == 2 and "rate limit" in res.stderr
    import socket

    with socket.create_server(("127.0.0.1", 0)) as busy:
        res = cli("study", "serve", path, "--port", busy.getsockname()[1])
    assert res.returncode == 2 and "cannot listen on 127.0.0.1" in res.stderr
    assert res.stderr.count("\n") == 1


# ---------------------------------------------------------------- a real browser
def _chrome():
    chromium, driver = shutil.which("chromium"), shutil.which("chromedriver")
    if not chromium or not driver:
        pytest.skip("headless Chromium is not installed (apt-get install chromium "
                    "chromium-driver; .ci/run does it as root)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = chromium  # both paths given: Selenium Manager downloads nothing
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu",
                "--window-size=1280,900"):
        opts.add_argument(arg)
    return webdriver.Chrome(service=Service(executable_path=driver), options=opts)


@pytest.mark.slow
def test_browser_rater_rates_reloads_resumes_finishes(server) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.ui import WebDriverWait

    path, (a, _), start, _procs = server
    browser = _chrome()
    base = start()
    wait = WebDriverWait(browser, 10)

    def visible(id_: str) -> bool:
        return browser.find_element(By.ID, id_).is_displayed()

    def press(*keys: str) -> None:
        ActionChains(browser).send_keys(*keys).perform()

    def rate_one(label_key: str, score_key: str) -> None:
        """Rate the trial on screen by keyboard, then pass any feedback or break page."""
        pos = browser.execute_script("return state.trial.position")
        wait.until(lambda d: d.find_element(By.ID, "stimulus").get_attribute("data-shown")
                   == str(pos))
        press(label_key, score_key, Keys.ENTER)
        wait.until(lambda d: d.execute_script("return state.done") == pos + 1)
        wait.until(lambda d: visible("message") or d.find_element(By.ID, "stimulus")
                   .get_attribute("data-shown") != str(pos) or not visible("rating"))
        if visible("message") and visible("continue"):
            press(Keys.ENTER)

    try:
        browser.get(f"{base}/r/{a.token}/")
        wait.until(lambda d: visible("intro"))
        assert "pilot" in browser.find_element(By.ID, "title").text
        assert "very realistic" in browser.find_element(By.ID, "instructions").text
        press(Keys.ENTER)
        for key in ("1", "2", "c", "3", "1"):  # 5 trials: training, then ratings
            wait.until(lambda d: visible("rating"))
            rate_one(key, "4")
        assert _n_answered(path, a.rater) == 5  # stored before the reload
        browser.refresh()
        wait.until(lambda d: visible("intro"))
        assert "5 of 9 images are already rated" in browser.find_element(By.ID, "welcome").text
        browser.find_element(By.ID, "start").click()  # then one trial by taps, as on a phone
        wait.until(lambda d: d.find_element(By.ID, "stimulus").get_attribute("data-shown")
                   == "5")
        browser.find_element(By.CSS_SELECTOR, "#labels button[data-label='fear']").click()
        browser.find_element(By.CSS_SELECTOR, "#scores button[data-score='2']").click()
        browser.find_element(By.ID, "confirm").click()
        wait.until(lambda d: d.execute_script("return state.done") == 6)
        if visible("message") and visible("continue"):
            browser.find_element(By.ID, "continue").click()
        while not (visible("message") and not visible("continue")):
            wait.until(lambda d: visible("rating") or visible("message"))
            if visible("rating"):
                rate_one("2", "5")
        assert "Thank you" in browser.find_element(By.ID, "message-text").text
    finally:
        browser.quit()
    con = sqlite3.connect(path)
    tapped = con.execute("SELECT label, naturalness FROM answers WHERE rater=? AND stimulus="
                         "(SELECT stimulus FROM web_plan WHERE rater=? AND position=5) UNION "
                         "SELECT label, naturalness FROM qc_answers WHERE rater=? AND item="
                         "(SELECT item FROM web_plan WHERE rater=? AND position=5)",
                         (a.rater,) * 4).fetchall()
    con.close()
    assert tapped == [("fear", 2)]
    with Study.open(path) as st:
        answers = st.answers(a.rater)
        assert len(answers) == 6 and all(x.response_ms > 0 for x in answers)
    assert _n_answered(path, a.rater) == 9  # + training, gold and trapping trial


@pytest.mark.slow
def test_render_qc_gold_and_training_from_a_photo(tmp_path: Path, cli) -> None:
    """The sample smiles: its neutral gold is the neutralised face; the extreme gold is a preset
    at 150 %; training renders the sample; all go into the study by ``study qc --faces``."""
    import cv2
    import numpy as np

    path = tmp_path / "s.db"
    create_from_renders(path, "pilot", LABELS, _renders()).close()
    res = cli("study", "qc", path, "--faces", "sample", "--training", "2", "--traps", "1")
    assert res.returncode == 0, res.stderr
    assert "2 training, 2 gold, 1 trapping" in res.stdout
    with Study.open(path) as st:
        items = qc_items(st)
        images = {i.id: cv2.imdecode(np.frombuffer(qc_image(st, i.id)[0], np.uint8), 1)
                  for i in items}
    gold = [i for i in items if i.kind == "gold"]
    assert [g.accept for g in gold] == [(CANNOT_TELL,), ("joy",)]
    assert gold[0].note.startswith("the photo neutralised") and gold[0].nat_min == 3
    assert [i.accept for i in items if i.kind == "training"] == [("joy",), ("sadness",)]
    neutral, joy = images[gold[0].id].astype(int), images[gold[1].id].astype(int)
    assert neutral.shape == joy.shape and np.abs(neutral - joy).mean() > 1.0
