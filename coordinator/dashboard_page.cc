// The dashboard page (see dashboard.h): one HTML document with its style and script. It polls
// /api/jobs and /api/workers every second and, for the selected job, /api/image.png and
// /api/record_map.png (shown side by side; the workers table shows each worker's map colour, from
// a copy of record_map.cc's palette); every
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
  #image, #record-map { image-rendering: pixelated; border: 1px solid #ccc; min-width: 64px;
           min-height: 64px; background: #111; vertical-align: top; }
  #record-map { margin-left: 12px; }
  .swatch { display: inline-block; width: 10px; height: 10px; margin-right: 5px;
            border: 1px solid #888; }
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
  <thead><tr><th>Id</th><th>Name</th><th>Host</th><th>Threads</th><th>State</th>
    <th>Current tile</th><th>Records computed</th><th>Records received</th><th>Last heard</th>
    <th>Violations</th></tr></thead>
  <tbody></tbody>
</table>

<h2 id="image-title">Image <span class="muted">(click a job)</span></h2>
<div><img id="image" alt=""><img id="record-map" alt="" title="record map: where records were
  computed, coloured by worker (see the workers table)"></div>
<div class="muted" id="record-map-title">Left: the image so far. Right: its record map.</div>

<script>
"use strict";
let token = sessionStorage.getItem("irfarm-token") || "";
let selected = null;      // job id whose image is shown
let imageUrl = null, mapUrl = null;
// record_map.cc's palette (8-bit sRGB): worker id w gets PALETTE[(w - 1) % 12].
const PALETTE = [[230, 25, 75], [60, 180, 75], [255, 225, 25], [0, 130, 200], [245, 130, 48],
                 [145, 30, 180], [70, 240, 240], [240, 50, 230], [210, 245, 60],
                 [250, 190, 212], [0, 128, 128], [220, 190, 255]];
function workerColor(id) { const c = PALETTE[(id - 1) % PALETTE.length]; return "rgb(" + c.join(",") + ")"; }
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

// Rows are made once per job and then updated in place, so that a priority being typed or a
// button being clicked is not replaced under the user by the next poll.
function jobRow(j) {
  let tr = document.getElementById("job-" + j.id);
  if (tr) return tr;
  tr = document.createElement("tr");
  tr.id = "job-" + j.id;
  tr.dataset.job = j.id;
  tr.onclick = () => { selected = j.id; refresh(); };
  for (const cls of ["id", "name", "state", "progress", "tiles", "rate", "eta", "records",
                     "priority", "actions"]) cell(tr, "", cls);
  const p = tr.querySelector("td.progress");
  const bar = document.createElement("progress");
  bar.max = 100;
  p.appendChild(bar);
  p.appendChild(document.createTextNode(" "));
  const pct = document.createElement("span");
  pct.className = "pct";
  p.appendChild(pct);
  const pr = tr.querySelector("td.priority");
  const shown = document.createElement("span");
  shown.className = "prio-value";
  pr.appendChild(shown);
  const inp = document.createElement("input");
  inp.className = "prio"; inp.type = "number";
  inp.onclick = (ev) => ev.stopPropagation();
  pr.appendChild(inp);
  button(pr, "set", "set-priority", () =>
    api("/api/priority?job=" + encodeURIComponent(j.id) + "&priority=" +
        encodeURIComponent(inp.value), true).then(refresh, showError));
  button(tr.querySelector("td.actions"), "cancel", "cancel", () =>
    api("/api/cancel?job=" + encodeURIComponent(j.id), true).then(refresh, showError));
  return tr;
}

function renderJobs(jobs) {
  const body = document.querySelector("#jobs tbody");
  const ids = new Set(jobs.map((j) => "job-" + j.id));
  for (const tr of Array.from(body.children)) if (!ids.has(tr.id)) tr.remove();
  jobs.forEach((j, index) => {
    const tr = jobRow(j);
    const set = (cls, text) => { tr.querySelector("td." + cls).textContent = text; };
    const state = j.state.replace("JOB_STATE_", "");
    const total = Math.max(1, j.tilesTotal), done = j.tilesDone;
    const pct = Math.floor(100 * done / total);
    const rate = done > 0 && j.elapsedSeconds > 0 ? done / j.elapsedSeconds : 0;
    const final = FINAL.includes(state);
    tr.className = j.id === selected ? "selected" : "";
    set("id", j.id);
    set("name", j.name.split("/").slice(-2).join("/"));
    set("state", state);
    tr.querySelector("progress").value = pct;
    tr.querySelector(".pct").textContent = pct + "%";
    set("tiles", done + "/" + j.tilesTotal);
    set("rate", rate > 0 ? rate.toFixed(2) + " tiles/s" : "");
    set("eta", final ? (j.elapsedSeconds > 0 ? "took " + duration(j.elapsedSeconds) : "")
                     : (rate > 0 ? duration((j.tilesTotal - done) / rate) : "?"));
    set("records", String(j.recordsMerged));
    // Final jobs show their priority as text; others an input (left alone while focused).
    const inp = tr.querySelector("input.prio");
    if (document.activeElement !== inp) inp.value = j.priority;
    tr.querySelector(".prio-value").textContent = final ? String(j.priority) : "";
    for (const el of [inp, tr.querySelector("button.set-priority"), tr.querySelector("button.cancel")])
      el.style.display = final ? "none" : "";
    // Keeps the server's order, moving a row only when it is out of place (moving a row takes
    // the focus away from its priority input).
    if (body.children[index] !== tr) body.insertBefore(tr, body.children[index] || null);
  });
}

function renderWorkers(cluster) {
  const body = document.querySelector("#workers tbody");
  body.textContent = "";
  for (const w of cluster.workers || []) {
    const tr = document.createElement("tr");
    tr.id = "worker-" + w.id;
    cell(tr, String(w.id));
    const name = cell(tr, w.name, "name");
    const sw = document.createElement("span");
    sw.className = "swatch";
    sw.style.background = workerColor(w.id);
    sw.dataset.rgb = PALETTE[(w.id - 1) % PALETTE.length].join(",");
    name.prepend(sw);
    cell(tr, w.peer);
    cell(tr, w.threads > 0 ? String(w.threads) : "all");
    cell(tr, w.quarantined ? "quarantined" : w.silent ? "silent" : w.hasLease ? "rendering" : "idle");
    cell(tr, w.hasLease ? w.leaseJob + " tile " + w.leaseTile : "", "tile");
    cell(tr, String(w.recordsComputed), "computed");
    cell(tr, String(w.recordsReceived), "received");
    cell(tr, w.secondsSinceHeard.toFixed(1) + " s ago");
    cell(tr, String(w.violations));
    body.appendChild(tr);
  }
}

// Loads `path` into <img id=id> through a blob URL (fetched with the token; same origin, so its
// pixels can be read back); the previous blob URL is released once the new one shows.
async function loadPng(id, path, prev, set) {
  const img = document.getElementById(id);
  const blob = await (await api(path + "?job=" + encodeURIComponent(selected))).blob();
  const url = URL.createObjectURL(blob);
  img.onload = () => { if (prev() && prev() !== url) URL.revokeObjectURL(prev()); set(url); };
  img.dataset.job = selected;
  img.src = url;
}
async function refreshImage() {
  const title = document.getElementById("image-title");
  const mapTitle = document.getElementById("record-map-title");
  if (!selected) return;
  title.textContent = "Image of " + selected;
  try {
    await loadPng("image", "/api/image.png", () => imageUrl, (u) => { imageUrl = u; });
  } catch (e) {
    title.textContent = "Image of " + selected + ": " + e.message;
  }
  try {
    await loadPng("record-map", "/api/record_map.png", () => mapUrl, (u) => { mapUrl = u; });
    mapTitle.textContent = "Left: the image so far. Right: where its records were computed, " +
                           "coloured by worker (swatches in the workers table).";
  } catch (e) {
    mapTitle.textContent = "Record map: " + e.message;
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
