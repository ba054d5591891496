// The fleet's page: everything arrives as server-sent events from /events; the buttons POST a
// console command to /api/command, which the server sends through the master's control socket.
"use strict";

const token = new URLSearchParams(location.search).get("token");
const fleetBody = document.querySelector("#fleet tbody");
const answers = {};          // robot id -> its last answer, kept across table redraws
const shownPlots = {};       // "robot/port" -> the report count its picture shows
const IMAGE_EVERY_MS = 2000; // a picture is redrawn at most this often
let lastMap = 0, mapCount = -1, mapTimer = null;

function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === "class") e.className = v; else e.setAttribute(k, v);
  }
  for (const c of children) e.append(c instanceof Node ? c : document.createTextNode(c ?? ""));
  return e;
}

function ago(ms) {
  return ms < 1000 ? `${ms} ms ago` : `${(ms / 1000).toFixed(1)} s ago`;
}

function reportsText(r) {
  if (!r) return "-";
  let t = `${r.first}-${r.last}`;
  if (r.dropped) t += ` (${r.dropped} dropped)`;
  if (r.gap) t += ` gap ${r.gap[0]}-${r.gap[1]}`;
  return t;
}

function buttons(id) {
  return el("td", {}, ...["start", "pause", "resume", "stop"].map(
    c => el("button", {"data-robot": String(id), "data-command": c}, c)));
}

function renderFleet(doc) {
  const master = document.getElementById("master");
  if (!doc.status) {
    master.textContent = `master unreachable: ${doc.error || "no status"}`;
    master.className = "down";
    return;
  }
  const s = doc.status, e = s.election;
  master.className = "";
  master.textContent = `master ${s.listening}` + (e ? `, ${e.role} of epoch ${e.epoch}` : "") +
    `, ${s.agents.length} robots`;
  const rows = s.agents.map(a => {
    const ans = answers[a.id];
    return el("tr", {"data-robot": String(a.id)},
      el("td", {}, String(a.id)),
      el("td", {"class": "state"}, el("span", {"class": `led ${a.led || "DARK"}`, "title": a.led || "no state yet"}),
         a.state),
      el("td", {"class": "behaviour"}, a.behaviour || "-"),
      el("td", {"class": "step"}, a.step ?? "-"),
      el("td", {}, a.battery || "-"),
      el("td", {}, ago(a.last_heard_ms_ago)),
      el("td", {}, e ? String(e.epoch) : "-"),
      el("td", {}, a.via ? String(a.via) : "direct"),
      el("td", {}, reportsText(s.reports[String(a.id)])),
      buttons(a.id),
      el("td", {"class": "answer" + (ans && !ans.ok ? " error" : "")}, ans ? ans.text : ""));
  });
  fleetBody.replaceChildren(...rows);
  document.getElementById("lost").textContent = s.lost.length
    ? "lost: " + s.lost.map(l => `${l.id} (${ago(l.lost_ms_ago)})`).join(", ") : "";
}

function addLog(lines) {
  const log = document.getElementById("log");
  for (const l of lines) {
    const t = new Date(l.t_ms).toLocaleTimeString();
    log.append(el("li", {"class": l.kind}, `${t}  ${l.agent == null ? "PC" : "robot " + l.agent}  ${l.kind}: ${l.text}`));
  }
  while (log.children.length > 500) log.firstChild.remove();
  log.scrollTop = log.scrollHeight;
}

function refreshMap(count) {
  mapCount = count;
  const due = lastMap + IMAGE_EVERY_MS - Date.now();
  if (mapTimer) return;
  mapTimer = setTimeout(() => {
    mapTimer = null;
    lastMap = Date.now();
    document.getElementById("map").src = `/map.svg?n=${mapCount}`;
  }, Math.max(0, due));
}

function renderSensors(sensors) {
  const box = document.getElementById("plots");
  for (const [robot, ports] of Object.entries(sensors)) {
    for (const [port, n] of Object.entries(ports)) {
      const key = `${robot}/${port}`;
      let img = document.getElementById(`plot-${robot}-${port}`);
      if (!img) {
        img = el("img", {"id": `plot-${robot}-${port}`, "alt": `robot ${robot}, ${port}`});
        box.append(img);
      }
      const shown = shownPlots[key];
      if (!shown || (shown.n !== n && Date.now() - shown.at >= IMAGE_EVERY_MS)) {
        shownPlots[key] = {n, at: Date.now()};
        img.src = `/plot/${robot}/${port}.svg?n=${n}`;
      }
    }
  }
}

async function send(robot, command) {
  const out = document.getElementById("answer");
  out.className = "";
  out.textContent = `${command} ${robot}: sent, waiting for the answer…`;
  const headers = {"Content-Type": "application/json"};
  if (token) headers["X-Ev3fleet-Token"] = token;
  let a;
  try {
    const r = await fetch("/api/command", {method: "POST", headers, body: JSON.stringify({robot, command})});
    a = await r.json();
  } catch (err) {
    a = {ok: false, error: String(err)};
  }
  const text = a.answers
    ? `${a.command}: ` + (a.answers.length ? a.answers.map(
        r => `${r.agent} ${r.answer}` + (r.reason ? ` (${r.reason})` : "")).join(", ") : "no robots")
    : (a.ok ? (a.answer || "ok") : (a.error || "error"));
  out.textContent = `${command} ${robot}: ${text}`;
  out.className = a.ok ? "" : "error";
  if (robot !== "all") {
    answers[robot] = {ok: a.ok, text};
    const cell = document.querySelector(`tr[data-robot="${robot}"] td.answer`);
    if (cell) {
      cell.textContent = text;
      cell.className = "answer" + (a.ok ? "" : " error");
    }
  }
}

document.addEventListener("click", ev => {
  const b = ev.target.closest("button[data-command]");
  if (b) send(b.dataset.robot, b.dataset.command);
});

const events = new EventSource("/events");
events.addEventListener("fleet", ev => renderFleet(JSON.parse(ev.data)));
events.addEventListener("log", ev => addLog(JSON.parse(ev.data)));
events.addEventListener("sensors", ev => renderSensors(JSON.parse(ev.data)));
events.addEventListener("map", ev => refreshMap(JSON.parse(ev.data)));
events.onerror = () => {
  const m = document.getElementById("master");
  m.textContent = "view server unreachable; retrying";
  m.className = "down";
};
