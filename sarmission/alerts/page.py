"""The operator page served at ``/`` by the feed server: one self-contained HTML document.

No external assets (the ground station may be offline): style (:mod:`page_style`), cards and
the operator's actions (:mod:`page_cards`) and the map (:mod:`page_map`) are inlined. Alerts
arrive over Server-Sent Events from ``/events`` (``hello`` once connected, ``alert`` for each
stored or new alert or candidate, ``update`` for every change to one; ``map``, ``track`` and
``area`` for the map); the buttons POST to ``/api/alerts/<id>/ack|confirm|dismiss``.

Opened as ``/?token=...`` the page removes the token from the address bar at once: the feed set
a cookie with the page, and the page's own requests carry that. When the feed refuses the event
stream (a new token after a restart, too many open streams) the page says why and retries.
"""

from sarmission.alerts.page_cards import CARDS_JS
from sarmission.alerts.page_map import map_js
from sarmission.alerts.page_style import PAGE_CSS

_BODY = """<body data-live="0">
<header>
  <h1>SAR alerts</h1>
  <div class="status"><span class="dot"></span><span id="status">connecting</span></div>
  <div class="counts"><span id="total">0</span> alerts &middot;
    <span class="unacked"><span id="unacked">0</span> unacknowledged</span> &middot;
    <span class="review"><span id="review">0</span> to review</span>
    <span id="taught" hidden>&middot; confidence learnt from <span id="decisions">0</span>
      of your decisions</span></div>
  <label>Operator <input id="operator" autocomplete="off" placeholder="your name"></label>
  <label class="toggle"><input type="checkbox" id="show-discarded"> show discarded</label>
  <nav>
    <a href="/alerts.geojson" download>GeoJSON</a>
    <a href="/alerts.kml" download>KML</a>
    <a href="/alerts.jsonl">JSON lines</a>
  </nav>
</header>
<main>
  <section class="mapbox"><svg id="map" role="img" aria-label="Map of alerts, candidates,
    dismissed positions, the drone's track and the mission area"></svg></section>
  <section class="list">
    <div id="alerts"></div>
    <div class="empty" id="empty">No alerts yet. Candidates and alerts appear here as soon as
      they are found.</div>
    <details class="help" id="help">
      <summary>What a card's evidence means</summary>
      <dl>
        <dt>2.1 s, 20 sightings</dt><dd>how long, and in how many frames, the target was
          seen and placed on the ground before the system decided</dd>
        <dt>in 80 % of frames</dt><dd>of the frames since it was first seen: a person stays
          in view, glint and foam flicker</dd>
        <dt>drift 0.2 m/s</dt><dd>its speed over the ground from a line through its positions:
          water and people drift slowly, glint and birds move fast</dd>
        <dt>0.6 m</dt><dd>its size on the ground across the line of sight: a person is
          between about 0.2 and 2.5 m, a boat larger</dd>
        <dt>extent 1.2 m</dt><dd>the object under the box measured against its surroundings
          (splash and shadow count with it): a boat the head boxed as a person is larger</dd>
        <dt>look change 0.08</dt><dd>how much its look changed over about a second, 0 the same
          to 1 unlike: a swimmer's arms and head move, a buoy or debris stays the same, and so
          does a person lying still</dd>
        <dt>score 0.84</dt><dd>the detector's mean score over the sightings: how much each
          crop looked like a person to it, not the chance that it is one</dd>
        <dt>20 % likely a person</dt><dd>how often alerts like it turned out to be people,
          learnt from your confirmations and dismissals on this mission; a range while there
          are still few</dd>
      </dl>
      <p>Every alert is for your eyes first: search within twice its &plusmn;.</p>
    </details>
  </section>
</main>
"""

#: Helpers shared by the cards and the map.
_CORE_JS = r"""
"use strict";
if (location.search) history.replaceState(null, "", location.pathname);
const alerts = new Map();
const list = document.getElementById("alerts");
const operator = document.getElementById("operator");
operator.value = localStorage.getItem("sar-operator") || "";
operator.addEventListener("change", () => localStorage.setItem("sar-operator", operator.value));
const showDiscarded = document.getElementById("show-discarded");
showDiscarded.addEventListener("change", () => {
  document.body.classList.toggle("show-discarded", showDiscarded.checked);
  scheduleMap();
});

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
async function refusal(r) {
  let why = "";
  try { why = (await r.json()).error || ""; } catch (e) { /* not JSON */ }
  return "HTTP " + r.status + (why ? ": " + why : "");
}
"""

#: The event stream: alerts, their changes and the map, with retries.
_LIVE_JS = r"""
function live(on, text) {
  document.body.dataset.live = on ? "1" : "0";
  document.getElementById("status").textContent = text;
}
let snapshotDone = false;
function connect() {
  const source = new EventSource("/events");
  source.addEventListener("hello", () => { snapshotDone = true; live(true, "live"); });
  source.addEventListener("alert", (e) => upsert(JSON.parse(e.data), snapshotDone));
  source.addEventListener("update", (e) => upsert(JSON.parse(e.data), true));
  source.addEventListener("map", (e) => setMap(JSON.parse(e.data)));
  source.addEventListener("track", (e) => addTrack(JSON.parse(e.data)));
  source.addEventListener("area", (e) => setArea(JSON.parse(e.data)));
  source.addEventListener("error", async () => {
    if (source.readyState !== EventSource.CLOSED) { live(false, "reconnecting\u2026"); return; }
    // the feed answered with an error, which EventSource does not retry: find out and retry
    let why = "feed unreachable";
    try {
      const r = await fetch("/healthz", {cache: "no-store"});
      why = r.status === 401 ? "access refused: open the feed address with ?token= again"
                             : (r.ok ? "event stream refused" : await refusal(r));
    } catch (e) { /* network down: keep the default */ }
    live(false, why + "; retrying\u2026");
    setTimeout(connect, 5000);
  });
}
connect();
scheduleMap();
setInterval(() => {
  for (const w of document.querySelectorAll(".when")) {
    const t = Number(w.dataset.t);
    w.textContent = utc(t) + " \u00b7 " + age(t);
  }
}, 1000);
"""

PAGE_HTML = (
    '<!doctype html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
    '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
    "<title>SAR alerts</title>\n<style>"
    + PAGE_CSS
    + "</style>\n</head>\n"
    + _BODY
    + "<script>"
    + _CORE_JS
    + CARDS_JS
    + map_js()
    + _LIVE_JS
    + "</script>\n</body>\n</html>\n"
)
