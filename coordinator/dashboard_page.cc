// The dashboard page (see dashboard.h): one HTML document with its style and script. It polls
// /api/jobs and /api/workers every second and, for the selected job, /api/image.png; every
// string from the server goes into the page as text (textContent), never as HTML, since job and
// worker names come from clients and workers.
#include "coordinator/dashboard.h"

namespace irfarm {

const char kDashboardHtml[] = R"HTML(<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>irfarm dashboard</title>
<style>
  body { font: 14px system-ui, sans-serif; margin: 1.5em; color: #222; }
  h1 { font-size: 20px; margin: 0 0 .5em; }
  h2 { font-size: 16px; margin: 1.2em 0 .4em; }
  table { border-collapse: collapse; }
  th, td { padding: 3px 10px; border-bottom: 1px solid #ddd; text-align: left; white-space: nowrap; }
  tr.selected { background: #eef4ff; }
  tbody tr { cursor: pointer; }
  progress { width: 160px; vertical-align: middle; }
  .muted { color: #888; }
  #error { color: #b00; }
  #image { image-rendering: pixelated; border: 1px solid #ccc; min-width: 64px; min-height: 64px;
           background: #111; }
  input.prio { width: 4em; }
</style>
</head>
<body>
<h1>irfarm</h1>
<div>Client token: <input id="token" type="password" size="40" autocomplete="off">
  <button id="use-token">Use</button> <span class="muted">(not needed without client tokens)</span>
  <span id="error"></span></div>

<h2>Jobs</h2>
<table id="jobs">
  <thead><tr><th>Job</th><th>Name</th><th>State</th><th>Progress</th><th>Tiles</th><th>Rate</th>
    <th>ETA</th><th>Records</th><th>Priority</th><th></th></tr></thead>
  <tbody></tbody>
</table>

<h2>Workers</h2>
<table id="workers">
  <thead><tr><th>Id</th><th>Name</th><th>Host</th><th>State</th><th>Current job</th>
    <th>Last heard</th><th>Violations</th></tr></thead>
  <tbody></tbody>
</table>

<h2 id="image-title">Image <span class="muted">(click a job)</span></h2>
<img id="image" alt="">

<script>
"use strict";
let token = sessionStorage.getItem("irfarm-token") || "";
let selected = null;      // job id whose image is shown
let imageUrl = null;
const FINAL = ["SUCCEEDED", "FAILED", "CANCELLED"];

document.getElementById("token").value = token;
document.getElementById("use-token").onclick = () => {
  token = document.getElementById("token").value.trim();
  sessionStorage.setItem("irfarm-token", token);
  refresh();
};

function headers(post) {
  const h = {};
  if (token) h["Authorization"] = "Bearer " + token;
  if (post) h["X-Irfarm-Request"] = "1";
  return h;
}
async function api(path, post) {
  const r = await fetch(path, {method: post ? "POST" : "GET", headers: headers(post),
                               cache: "no-store"});
  if (!r.ok) throw new Error(path.split("?")[0] + ": " + r.status + " " + (await r.text()));
  return r;
}
function showError(e) { document.getElementById("error").textContent = e ? String(e.message || e) : ""; }

function duration(s) {
  if (!(s >= 0) || !isFinite(s)) return "?";
  s = Math.round(s);
  if (s < 60) return s + "s";
  if (s < 3600) return Math.floor(s / 60) + "m" + String(s % 60).padStart(2, "0") + "s";
  return Math.floor(s / 3600) + "h" + String(Math.floor(s % 3600 / 60)).padStart(2, "0") + "m";
}
function cell(tr, text, cls) {
  const td = document.createElement("td");
  td.textContent = text;
  if (cls) td.className = cls;
  tr.appendChild(td);
  return td;
}
function button(td, label, cls, onclick) {
  const b = document.createElement("button");
  b.textContent = label;
  b.className = cls;
  b.onclick = (ev) => { ev.stopPropagation(); onclick(); };
  td.appendChild(b);
  return b;
}

function renderJobs(jobs) {
  const body = document.querySelector("#jobs tbody");
  body.textContent = "";
  for (const j of jobs) {
    const state = j.state.replace("JOB_STATE_", "");
    const total = Math.max(1, j.tilesTotal), done = j.tilesDone;
    const pct = Math.floor(100 * done / total);
    const rate = done > 0 && j.elapsedSeconds > 0 ? done / j.elapsedSeconds : 0;
    const tr = document.createElement("tr");
    tr.id = "job-" + j.id;
    tr.dataset.job = j.id;
    if (j.id === selected) tr.className = "selected";
    tr.onclick = () => { selected = j.id; refresh(); };
    cell(tr, j.id, "id");
    cell(tr, j.name.split("/").slice(-2).join("/"), "name");
    cell(tr, state, "state");
    const p = cell(tr, "", "progress");
    const bar = document.createElement("progress");
    bar.max = 100; bar.value = pct;
    p.appendChild(bar);
    p.appendChild(document.createTextNode(" "));
    const t = document.createElement("span");
    t.className = "pct"; t.textContent = pct + "%";
    p.appendChild(t);
    cell(tr, done + "/" + j.tilesTotal, "tiles");
    cell(tr, rate > 0 ? rate.toFixed(2) + " tiles/s" : "", "rate");
    const final = FINAL.includes(state);
    cell(tr, final ? (j.elapsedSeconds > 0 ? "took " + duration(j.elapsedSeconds) : "")
                   : (rate > 0 ? duration((j.tilesTotal - done) / rate) : "?"), "eta");
    cell(tr, String(j.recordsMerged), "records");
    const pr = cell(tr, "", "priority");
    if (final) {
      pr.textContent = String(j.priority);
    } else {
      const inp = document.createElement("input");
      inp.className = "prio"; inp.type = "number"; inp.value = j.priority;
      inp.onclick = (ev) => ev.stopPropagation();
      pr.appendChild(inp);
      button(pr, "set", "set-priority", () =>
        api("/api/priority?job=" + encodeURIComponent(j.id) + "&priority=" +
            encodeURIComponent(inp.value), true).then(refresh, showError));
    }
    const act = cell(tr, "", "actions");
    if (!final)
      button(act, "cancel", "cancel", () =>
        api("/api/cancel?job=" + encodeURIComponent(j.id), true).then(refresh, showError));
    body.appendChild(tr);
  }
}

function renderWorkers(cluster) {
  const body = document.querySelector("#workers tbody");
  body.textContent = "";
  for (const w of cluster.workers || []) {
    const tr = document.createElement("tr");
    tr.id = "worker-" + w.id;
    cell(tr, String(w.id));
    cell(tr, w.name);
    cell(tr, w.peer);
    cell(tr, w.quarantined ? "quarantined" : w.silent ? "silent" : w.hasLease ? "rendering" : "idle");
    cell(tr, w.hasLease ? w.leaseJob : "");
    cell(tr, w.secondsSinceHeard.toFixed(1) + " s ago");
    cell(tr, String(w.violations));
    body.appendChild(tr);
  }
}

async function refreshImage() {
  const img = document.getElementById("image");
  const title = document.getElementById("image-title");
  if (!selected) return;
  title.textContent = "Image of " + selected;
  try {
    const blob = await (await api("/api/image.png?job=" + encodeURIComponent(selected))).blob();
    const url = URL.createObjectURL(blob);
    img.onload = () => { if (imageUrl && imageUrl !== url) URL.revokeObjectURL(imageUrl); imageUrl = url; };
    img.dataset.job = selected;
    img.src = url;
  } catch (e) {
    title.textContent = "Image of " + selected + ": " + e.message;
  }
}

let busy = false;
async function refresh() {
  if (busy) return;
  busy = true;
  try {
    const jobs = (await (await api("/api/jobs")).json()).jobs || [];
    if (!selected && jobs.length) selected = jobs[jobs.length - 1].id;
    renderJobs(jobs);
    renderWorkers(await (await api("/api/workers")).json());
    await refreshImage();
    showError(null);
  } catch (e) {
    showError(e);
  } finally {
    busy = false;
  }
}
refresh();
setInterval(refresh, 1000);
</script>
</body>
</html>
)HTML";

}  // namespace irfarm
