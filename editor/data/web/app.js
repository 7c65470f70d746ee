// FAP Studio remote rating page: the same trial design as the in-app rating window.
// Step 1: the emotion (keys 1..N, 0 or C = "cannot tell"); step 2: naturalness (keys 1-5 after
// the emotion, or F1-F5); Backspace/Esc back to step 1; Enter/Space confirm. Touch: tap buttons.
// Every answer is stored by the server at once; reopening the link resumes at the next image.
"use strict";

const $ = (id) => document.getElementById(id);
let state = null;        // the server's state (labels, wording, progress, current trial)
let label = null;        // chosen emotion of the current trial
let score = null;        // chosen naturalness of the current trial
let step = "label";
let shownAt = null;      // performance.now() when the image appeared
let busy = false;
let page = "intro";

function el(tag, attrs, ...kids) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  for (const k of kids) e.append(k);
  return e;
}
const kbd = (t) => el("kbd", {}, t);

async function api(path, body) {
  const init = body === undefined ? {} : {
    method: "POST", headers: {"Content-Type": "application/json"}, body: JSON.stringify(body)};
  const r = await fetch(path, {cache: "no-store", ...init});
  let data = null;
  try { data = await r.json(); } catch (e) { data = {error: r.statusText}; }
  return {status: r.status, data};
}

function show(name) {
  page = name;
  for (const id of ["intro", "rating", "message"]) $(id).hidden = id !== name;
}

function message(nodes, button) {
  $("message-text").replaceChildren(...nodes);
  $("continue").textContent = button || "Continue (Enter)";
  $("continue").hidden = button === null;
  show("message");
}

function fatal(text) {
  message([el("h1", {}, "Cannot continue"), el("p", {}, text)], null);
}

function instructions() {
  const s = state;
  const keys = [];
  s.labels.slice(0, 9).forEach((lab, i) => { keys.push(kbd(String(i + 1)), ` ${lab}, `); });
  const nat = [];
  s.naturalness.forEach(([k, w], i) => {
    nat.push(kbd(String(k)), ` ${w}${i + 1 < s.naturalness.length ? ", " : ""}`);
  });
  const rest = s.total - s.training;
  const parts = [
    el("p", {}, `You will see ${rest} face images, one at a time` +
       (s.training ? `, after ${s.training} practice images that show the intended answer.` : ".") +
       " For each image:"),
    el("p", {}, "1. Which emotion does the face show? ", ...keys, kbd("0"), " or ", kbd("C"),
       ` ${s.cannot_tell}.`),
    el("p", {}, "2. How natural does it look? ", ...nat,
       " (keys 1–5 after the emotion, or F1–F5)."),
    el("p", {}, "Confirm with ", kbd("Enter"), " or ", kbd("Space"),
       ". On a touch screen, tap the buttons. Answers cannot be changed once confirmed and " +
       "are saved immediately, so you may close this page and come back with the same link. " +
       "Answer spontaneously; response time is recorded."),
  ];
  $("title").textContent = s.study;
  $("instructions").replaceChildren(...parts);
  const w = $("welcome");
  w.hidden = s.done === 0;
  w.textContent = `Welcome back: ${s.done} of ${s.total} images are already rated; ` +
    "you continue where you stopped.";
}

function buildButtons() {
  const labels = [...state.labels, state.cannot_tell].map((lab, i) => {
    const key = lab === state.cannot_tell ? "0/C" : (i < 9 ? String(i + 1) : "");
    const b = el("button", {type: "button", "data-label": lab},
                 el("span", {class: "key"}, key), ` ${lab}`);
    b.addEventListener("click", () => chooseLabel(lab));
    return b;
  });
  $("labels").replaceChildren(...labels);
  const scores = state.naturalness.map(([k, w]) => {
    const b = el("button", {type: "button", "data-score": String(k)},
                 el("span", {class: "key"}, String(k)), ` ${w}`);
    b.addEventListener("click", () => chooseScore(k));
    return b;
  });
  $("scores").replaceChildren(...scores);
}

function refresh() {
  const n = Math.min(state.labels.length, 9);
  $("step").textContent = step === "label"
    ? `Step 1: which emotion? keys 1–${n}, 0 or C = ${state.cannot_tell}`
    : "Step 2: how natural? keys 1–5 or F1–F5; Backspace = change the emotion";
  for (const b of $("labels").children) b.classList.toggle("selected", b.dataset.label === label);
  for (const b of $("scores").children) {
    b.classList.toggle("selected", Number(b.dataset.score) === score);
  }
  $("labels").classList.toggle("inactive", step !== "label");
  $("scores").classList.toggle("inactive", step !== "naturalness");
  $("confirm").disabled = busy || label === null || score === null;
}

function showTrial() {
  const t = state.trial;
  if (!t) { finished(); return; }
  label = null; score = null; step = "label"; shownAt = null;
  $("hint").textContent = "";
  const done = state.done;
  $("progress-text").textContent = `${done + 1} / ${state.total}`;
  $("progress").value = done / state.total;
  $("phase").textContent = t.training ? "practice" : "";
  const img = $("stimulus");
  img.onload = () => { shownAt = performance.now(); img.dataset.shown = String(t.position); };
  img.src = t.image;
  show("rating");
  refresh();
}

function finished() {
  $("progress").value = 1;
  message([el("h1", {}, "Thank you!"),
           el("p", {}, `All ${state.total} images are rated (${state.done} answers saved). ` +
                       "You can close this page.")], null);
}

function chooseLabel(lab) {
  if (page !== "rating" || busy) return;
  label = lab; step = "naturalness"; $("hint").textContent = ""; refresh();
}

function chooseScore(k) {
  if (page !== "rating" || busy) return;
  score = k;
  if (label !== null) step = "naturalness";
  $("hint").textContent = ""; refresh();
}

async function confirmAnswer() {
  if (busy) return;
  if (label === null || score === null) {
    $("hint").textContent = "Choose an emotion and a naturalness score first.";
    return;
  }
  if (shownAt === null) { $("hint").textContent = "Wait for the image to appear."; return; }
  busy = true; refresh();
  const answer = {position: state.trial.position, label, naturalness: score,
                  response_ms: Math.round((performance.now() - shownAt) * 10) / 10};
  let r;
  try {
    r = await api("api/answer", answer);
  } catch (e) {
    busy = false; refresh();
    $("hint").textContent = "The answer could not be sent (network). Press Enter to try again.";
    return;
  }
  busy = false;
  if (r.status === 409) {           // already stored (e.g. a retry after a lost response)
    await load(false);
    return;
  }
  if (r.status !== 200) {
    refresh();
    $("hint").textContent = r.status === 429 ? "Too fast: please wait a few seconds."
      : `Not saved: ${r.data.error || r.status}`;
    if (r.status === 403) fatal(r.data.error);
    return;
  }
  state = r.data;
  if (state.feedback) {
    const f = state.feedback;
    message([el("h1", {class: f.correct ? "ok" : "bad"}, f.correct ? "Correct" : "Not quite"),
             el("p", {}, `This practice face was meant to show: ${f.intended}.`),
             el("p", {}, state.trial && !state.trial.training
               ? "Practice is over; the rating starts now." : "")],
            "Continue (Enter)");
  } else if (state.break_due) {
    message([el("h1", {}, "Break"),
             el("p", {}, `${state.done} of ${state.total} images rated. Take a short rest.`)],
            "Continue (Enter)");
  } else {
    showTrial();
  }
}

function onKey(ev) {
  const k = ev.key;
  if (page === "intro" || (page === "message" && !$("continue").hidden)) {
    if (k === "Enter" || k === " ") { ev.preventDefault(); (page === "intro" ? $("start") : $("continue")).click(); }
    return;
  }
  if (page !== "rating") return;
  const fk = /^F([1-5])$/.exec(k);
  if (k === "Enter" || k === " ") { ev.preventDefault(); confirmAnswer(); }
  else if (fk) { ev.preventDefault(); chooseScore(Number(fk[1])); }
  else if (k === "Backspace" || k === "Escape") { ev.preventDefault(); step = "label"; refresh(); }
  else if (step === "label" && (k === "0" || k === "c" || k === "C")) chooseLabel(state.cannot_tell);
  else if (step === "label" && /^[1-9]$/.test(k) && Number(k) <= Math.min(state.labels.length, 9)) {
    chooseLabel(state.labels[Number(k) - 1]);
  } else if (step === "naturalness" && /^[1-5]$/.test(k)) chooseScore(Number(k));
}

async function load(intro) {
  let r;
  try { r = await api("api/state"); } catch (e) { fatal("The server cannot be reached."); return; }
  if (r.status !== 200) { fatal(r.data.error || `error ${r.status}`); return; }
  state = r.data;
  if (intro) { buildButtons(); instructions(); }
  if (!state.trial) finished();
  else if (intro) show("intro");
  else showTrial();
}

document.addEventListener("keydown", onKey);
$("start").addEventListener("click", () => showTrial());
$("continue").addEventListener("click", () => showTrial());
$("confirm").addEventListener("click", () => confirmAnswer());
load(true);
