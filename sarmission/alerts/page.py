"""The operator page served at ``/`` by the feed server: one self-contained HTML document.

No external assets (the ground station may be offline). Alerts arrive over Server-Sent Events
from ``/events`` (``hello`` once connected, ``alert`` for each stored or new alert, ``update``
for acknowledgements, deliveries and positions found later); the Acknowledge button POSTs to
``/api/alerts/<id>/ack``. Light, high-contrast theme for use in daylight.

Opened as ``/?token=...`` the page removes the token from the address bar at once: the feed set
a cookie with the page, and the page's own requests carry that. When the feed refuses the event
stream (a new token after a restart, too many open streams) the page says why and retries.
"""

PAGE_HTML = """<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>SAR alerts</title>
<style>
  :root { --red: #c62828; --amber: #b26a00; --green: #2e7d32; --ink: #111; --muted: #555;
          --line: #d0d0d0; --bg: #f4f4f2; }
  * { box-sizing: border-box; }
  body { margin: 0; font: 16px/1.4 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif;
         color: var(--ink); background: var(--bg); }
  header { position: sticky; top: 0; z-index: 1; display: flex; flex-wrap: wrap; gap: 12px 24px;
           align-items: center; padding: 10px 20px; background: #1d2733; color: #fff; }
  header h1 { margin: 0; font-size: 20px; letter-spacing: .02em; }
  .status { display: flex; align-items: center; gap: 8px; font-weight: 600; }
  .dot { width: 12px; height: 12px; border-radius: 50%; background: var(--amber); }
  body[data-live="1"] .dot { background: #4caf50; }
  .counts { font-weight: 600; }
  .counts .unacked { color: #ff8a80; }
  header label { font-size: 14px; }
  header input { font: inherit; font-size: 14px; padding: 3px 6px; width: 10em; border: 0;
                 border-radius: 4px; }
  header nav { margin-left: auto; font-size: 14px; }
  header nav a { color: #cfe3ff; margin-left: 12px; }
  main { max-width: 1100px; margin: 0 auto; padding: 16px 20px 40px; }
  .empty { color: var(--muted); text-align: center; padding: 48px 0; font-size: 18px; }
  .alert { display: grid; grid-template-columns: 136px 1fr auto; gap: 6px 18px;
           align-items: center; background: #fff; border: 1px solid var(--line);
           border-left: 8px solid var(--red); border-radius: 6px; padding: 12px 16px;
           margin-bottom: 12px; box-shadow: 0 1px 2px rgba(0,0,0,.06); }
  .alert.fresh { animation: flash 1.6s ease-out 2; }
  @keyframes flash { 0% { background: #ffebee; } 100% { background: #fff; } }
  .alert[data-acknowledged="1"] { border-left-color: var(--green); background: #fafafa; }
  .alert > * { grid-column: 2; }
  .alert > .thumb { grid-column: 1; grid-row: 1 / span 3; }
  .alert > .side { grid-column: 3; grid-row: 1 / span 3; text-align: right; }
  .thumb { width: 128px; height: 128px; border-radius: 4px; background: #222;
           object-fit: cover; image-rendering: pixelated; }
  .nothumb { display: flex; align-items: center; justify-content: center; color: #aaa;
             font-size: 13px; }
  .title { font-size: 22px; font-weight: 700; }
  .title .score { font-weight: 600; color: var(--muted); margin-left: 6px; }
  .title .target { font-size: 15px; font-weight: 600; color: var(--muted); margin-left: 10px; }
  .where { display: flex; flex-wrap: wrap; align-items: baseline; gap: 4px 14px; }
  .coords { font: 600 20px/1.2 ui-monospace, "DejaVu Sans Mono", Menlo, Consolas, monospace;
            color: var(--ink); background: #eef3fb; border: 1px solid #b9cbe6;
            border-radius: 4px; padding: 3px 8px; cursor: copy; }
  .coords:hover { background: #dde8f8; }
  .coords.copied { background: #dff3e0; border-color: #8bc34a; }
  .err { font-weight: 600; }
  .nopos { color: var(--amber); font-weight: 700; }
  .meta { color: var(--muted); font-size: 14px; }
  .chip { display: inline-block; font-size: 12px; font-weight: 600; padding: 1px 7px;
          border-radius: 10px; background: #e8eaf6; color: #283593; margin-right: 6px; }
  .chip.refused { background: #fde7e7; color: #8b1a1a; }
  .ack { font: 700 16px system-ui, sans-serif; color: #fff; background: var(--red); border: 0;
         border-radius: 6px; padding: 12px 20px; cursor: pointer; min-width: 150px; }
  .ack:hover { filter: brightness(1.1); }
  .ack:disabled { opacity: .6; cursor: wait; }
  .acked { color: var(--green); font-weight: 700; }
  .ackerr { color: var(--red); font-size: 13px; }
</style>
</head>
<body data-live="0">
<header>
  <h1>SAR alerts</h1>
  <div class="status"><span class="dot"></span><span id="status">connecting</span></div>
  <div class="counts"><span id="total">0</span> alerts &middot;
    <span class="unacked"><span id="unacked">0</span> unacknowledged</span></div>
  <label>Operator <input id="operator" autocomplete="off" placeholder="your name"></label>
  <nav>
    <a href="/alerts.geojson" download>GeoJSON</a>
    <a href="/alerts.kml" download>KML</a>
    <a href="/alerts.jsonl">JSON lines</a>
  </nav>
</header>
<main>
  <div id="alerts"></div>
  <div class="empty" id="empty">No alerts yet. New alerts appear here as soon as they are
    confirmed.</div>
</main>
<script>
"use strict";
if (location.search) history.replaceState(null, "", location.pathname);
const alerts = new Map();
const list = document.getElementById("alerts");
const operator = document.getElementById("operator");
operator.value = localStorage.getItem("sar-operator") || "";
operator.addEventListener("change", () => localStorage.setItem("sar-operator", operator.value));

function el(tag, cls, text) {
  const e = document.createElement(tag);
  if (cls) e.className = cls;
  if (text !== undefined) e.textContent = text;
  return e;
}
function utc(t) { return new Date(t * 1000).toISOString().slice(11, 19) + " UTC"; }
function age(t) {
  const s = Math.max(0, Math.round(Date.now() / 1000 - t));
  if (s < 60) return s + " s ago";
  if (s < 3600) return Math.floor(s / 60) + " min ago";
  return Math.floor(s / 3600) + " h " + Math.floor((s % 3600) / 60) + " min ago";
}
async function copyText(text) {
  if (navigator.clipboard && window.isSecureContext) {
    try { await navigator.clipboard.writeText(text); return; } catch (e) { /* fall back */ }
  }
  const ta = el("textarea");
  ta.value = text;
  ta.style.position = "fixed";
  ta.style.opacity = "0";
  document.body.appendChild(ta);
  ta.select();
  document.execCommand("copy");
  ta.remove();
}
async function acknowledge(a, button, side) {
  button.disabled = true;
  try {
    const r = await fetch("/api/alerts/" + encodeURIComponent(a.alert_id) + "/ack", {
      method: "POST", headers: {"Content-Type": "application/json"},
      body: JSON.stringify({by: operator.value.trim() || "operator"})});
    if (!r.ok) throw new Error(await refusal(r));
    upsert(await r.json(), false);
  } catch (e) {
    button.disabled = false;
    side.appendChild(el("div", "ackerr", "not acknowledged: " + e.message));
  }
}
async function refusal(r) {
  let why = "";
  try { why = (await r.json()).error || ""; } catch (e) { /* not JSON */ }
  return "HTTP " + r.status + (why ? ": " + why : "");
}
function render(a) {
  const card = el("article", "alert");
  card.dataset.alertId = a.alert_id;
  card.dataset.acknowledged = a.acknowledged ? "1" : "0";
  if (a.thumbnail) {
    const img = el("img", "thumb");
    img.src = a.thumbnail;
    img.alt = a.class_name + " thumbnail";
    card.appendChild(img);
  } else {
    card.appendChild(el("div", "thumb nothumb", "no image"));
  }
  const title = el("div", "title", a.class_name);
  title.appendChild(el("span", "score", a.score.toFixed(2)));
  title.appendChild(el("span", "target", "target " + a.target_id
    + (a.short_id ? " \u00b7 " + a.short_id : "")));
  card.appendChild(title);
  const where = el("div", "where");
  if (a.position) {
    const full = a.position.lat + ", " + a.position.lon;
    const c = el("button", "coords", a.position.lat.toFixed(6) + ", " + a.position.lon.toFixed(6));
    c.title = "Click to copy " + full;
    c.addEventListener("click", async () => {
      await copyText(full);
      c.classList.add("copied");
      setTimeout(() => c.classList.remove("copied"), 900);
    });
    where.appendChild(c);
    if (a.error_m !== null) {
      where.appendChild(el("span", "err", "\\u00b1" + Math.max(1, Math.round(a.error_m)) + " m"));
    }
  } else {
    const note = a.position_note ? ": " + a.position_note : "";
    where.appendChild(el("span", "nopos", "Position unknown" + note));
  }
  card.appendChild(where);
  const meta = el("div", "meta");
  const when = el("span", "when");
  when.dataset.t = a.lock_time;
  when.textContent = utc(a.lock_time) + " \\u00b7 " + age(a.lock_time);
  meta.appendChild(when);
  meta.appendChild(document.createTextNode(" \\u00b7 frame " + a.frame_index + " "));
  const names = {mavlink_loiter: "loiter", mavlink_roi: "camera ROI",
                 mavlink_mission: "mission visit"};
  const sent = a.sent || {};
  if (sent.mavlink) {
    meta.appendChild(el("span", "chip", "STATUSTEXT sent " + sent.mavlink.count
      + "\u00d7 (no acknowledgement)"));
  }
  for (const ch of Object.keys(a.delivered)) {
    if (names[ch]) meta.appendChild(el("span", "chip", names[ch] + " acknowledged"));
  }
  for (const [ch, r] of Object.entries(a.refused || {})) {
    if (names[ch]) {
      meta.appendChild(el("span", "chip refused", names[ch] + " refused: " + r.reason));
    }
  }
  if (a.delivered.cot !== undefined) meta.appendChild(el("span", "chip", "TAK sent"));
  card.appendChild(meta);
  const side = el("div", "side");
  if (a.acknowledged) {
    side.appendChild(el("div", "acked", "\\u2713 Acknowledged"));
    side.appendChild(el("div", "meta", "by " + a.ack_by + " at " + utc(a.ack_time)));
  } else {
    const b = el("button", "ack", "Acknowledge");
    b.addEventListener("click", () => acknowledge(a, b, side));
    side.appendChild(b);
  }
  card.appendChild(side);
  return card;
}
function upsert(a, fresh) {
  const card = render(a);
  const old = alerts.get(a.alert_id);
  if (old) {
    old.card.replaceWith(card);
  } else {
    list.prepend(card);
    if (fresh) card.classList.add("fresh");
  }
  alerts.set(a.alert_id, {alert: a, card: card});
  counts();
}
function counts() {
  let unacked = 0;
  for (const v of alerts.values()) if (!v.alert.acknowledged) unacked++;
  document.getElementById("total").textContent = alerts.size;
  document.getElementById("unacked").textContent = unacked;
  document.getElementById("empty").hidden = alerts.size > 0;
  document.title = (unacked ? "(" + unacked + ") " : "") + "SAR alerts";
}
function live(on, text) {
  document.body.dataset.live = on ? "1" : "0";
  document.getElementById("status").textContent = text;
}
let snapshotDone = false;
function connect() {
  const source = new EventSource("/events");
  source.addEventListener("hello", () => { snapshotDone = true; live(true, "live"); });
  source.addEventListener("alert", (e) => upsert(JSON.parse(e.data), snapshotDone));
  source.addEventListener("update", (e) => upsert(JSON.parse(e.data), false));
  source.addEventListener("error", async () => {
    if (source.readyState !== EventSource.CLOSED) { live(false, "reconnecting\\u2026"); return; }
    // the feed answered with an error, which EventSource does not retry: find out and retry
    let why = "feed unreachable";
    try {
      const r = await fetch("/healthz", {cache: "no-store"});
      why = r.status === 401 ? "access refused: open the feed address with ?token= again"
                             : (r.ok ? "event stream refused" : await refusal(r));
    } catch (e) { /* network down: keep the default */ }
    live(false, why + "; retrying\\u2026");
    setTimeout(connect, 5000);
  });
}
connect();
setInterval(() => {
  for (const w of document.querySelectorAll(".when")) {
    const t = Number(w.dataset.t);
    w.textContent = utc(t) + " \\u00b7 " + age(t);
  }
}, 1000);
</script>
</body>
</html>
"""
