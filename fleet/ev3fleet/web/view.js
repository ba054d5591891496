// The fleet's page: everything arrives as server-sent events from /events; the buttons POST a
// console command to /api/command, which the server sends through the master's control socket.
"use strict";

const token = new URLSearchParams(location.search).get("token");
const fleetBody = document.querySelector("#fleet tbody");
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

// A robot's row, made once: its cells are updated in place, so a button under the pointer or with
// the keyboard's focus stays the same element while the fleet changes around it.
const CELLS = ["id", "state", "behaviour", "step", "battery", "heard", "epoch", "via", "reports"];

function rowOf(id) {
  let tr = fleetBody.querySelector(`tr[data-robot="${id}"]`);
  if (!tr) {
    tr = el("tr", {"data-robot": String(id)}, ...CELLS.map(c => el("td", {"class": c})), buttons(id),
            el("td", {"class": "answer"}));
    tr.querySelector("td.state").append(el("span", {"class": "led DARK"}), el("span", {"class": "name"}));
    const after = [...fleetBody.children].find(r => Number(r.dataset.robot) > id);
    fleetBody.insertBefore(tr, after || null);
  }
  return tr;
}

function setText(tr, cls, text) {
  const td = tr.querySelector(`td.${cls}`);
  if (td.textContent !== text) td.textContent = text;
}

function renderFleet(doc) {
  const master = document.getElementById("master");
  const problems = [doc.error && `master unreachable: ${doc.error}`, doc.record_error && `record: ${doc.record_error}`]
    .filter(Boolean);
  const s = doc.status;
  if (!s) {
    master.textContent = problems.join("; ") || "waiting for the master";
    master.className = "down";
    return;
  }
  const e = s.election;
  master.className = problems.length ? "down" : "";
  master.textContent = (problems.length ? problems.join("; ") + " (the table is the last one heard) - " : "") +
    `master ${s.listening}` + (e ? `, ${e.role} of epoch ${e.epoch}` : "") + `, ${s.agents.length} robots`;
  const seen = new Set();
  for (const a of s.agents) {
    seen.add(String(a.id));
    const tr = rowOf(a.id);
    setText(tr, "id", String(a.id));
    const built = a.model ? `model ${a.model}: ${(a.devices || []).join(", ") || "no devices"}` : "model not known";
    const idCell = tr.querySelector("td.id");
    if (idCell.title !== built) idCell.title = built;
    const led = tr.querySelector("td.state span.led");
    const ledClass = `led ${a.led || "DARK"}`;
    if (led.className !== ledClass) led.className = ledClass;
    led.title = a.led || "no state yet";
    const name = tr.querySelector("td.state span.name");
    if (name.textContent !== a.state) name.textContent = a.state;
    setText(tr, "behaviour", a.behaviour || "-");
    setText(tr, "step", a.step ?? "-");
    setText(tr, "battery", a.battery || "-");
    setText(tr, "heard", ago(a.last_heard_ms_ago));
    setText(tr, "epoch", e ? String(e.epoch) : "-");
    setText(tr, "via", a.via ? String(a.via) : "direct");
    setText(tr, "reports", reportsText(s.reports[String(a.id)]));
  }
  for (const tr of [...fleetBody.children]) if (!seen.has(tr.dataset.robot)) tr.remove();
  document.getElementById("lost").textContent = s.lost.length
    ? "lost: " + s.lost.map(l => `${l.id} (${ago(l.lost_ms_ago)})`).join(", ") : "";
}

function addLog(lines, replace = false) {
  const log = document.getElementById("log");
  if (replace) log.replaceChildren();  // the server's backlog when the stream (re)connects
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

let lastSensors = {}, sensorsTimer = null;

function renderSensors(sensors) {
  lastSensors = sensors;
  const box = document.getElementById("plots");
  let later = false;
  for (const [robot, ports] of Object.entries(sensors)) {
    for (const [port, n] of Object.entries(ports)) {
      const key = `${robot}/${port}`;
      let img = document.getElementById(`plot-${robot}-${port}`);
      if (!img) {
        img = el("img", {"id": `plot-${robot}-${port}`, "alt": `robot ${robot}, ${port}`});
        box.append(img);
      }
      const shown = shownPlots[key];
      if (shown && shown.n === n) continue;
      if (!shown || Date.now() - shown.at >= IMAGE_EVERY_MS) {
        shownPlots[key] = {n, at: Date.now()};
        img.src = `/plot/${robot}/${port}.svg?n=${n}`;
      } else {
        later = true;  // drawn too recently: once more when its time comes, even if no report follows
      }
    }
  }
  if (later && !sensorsTimer)
    sensorsTimer = setTimeout(() => { sensorsTimer = null; renderSensors(lastSensors); }, IMAGE_EVERY_MS);
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
events.addEventListener("backlog", ev => addLog(JSON.parse(ev.data), true));
events.addEventListener("sensors", ev => renderSensors(JSON.parse(ev.data)));
events.addEventListener("map", ev => refreshMap(JSON.parse(ev.data)));
events.onerror = () => {
  const m = document.getElementById("master");
  m.textContent = "view server unreachable; retrying";
  m.className = "down";
};
