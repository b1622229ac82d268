"""The operator page's map (JavaScript): drawn into an inline SVG, without network tiles.

Positions are projected to local metres around the centre of everything shown (equirectangular:
east = dlon * R cos(lat0), north = dlat * R, exact to well under a metre over a search area of a
few kilometres), then scaled to fit the SVG with north up. Drawn, bottom to top: the mission
area (dashed polygon), the drone's track (blue line, a dot at its newest point), dismissed
positions (grey discs of their suppression radius, to scale), discarded candidates (hollow, only
with "show discarded"), candidates (amber) and confirmed alerts (red), a scale bar and a north
arrow. Each marker is a ``<g class="marker KIND" data-alert=ID>`` with a 44 px touch
target; a tap highlights the alert's card and a tap on a card rings its marker. Marker colours
are fixed (:data:`MARKER_COLOURS`) so a screenshot can be checked.
"""

import json

#: Fill of each marker's centre, as drawn (tests check screenshots for them).
MARKER_COLOURS = {"alert": "#d32f2f", "candidate": "#f2a900", "dismissed": "#616161"}

MAP_JS = r"""
const mapView = {mission: null, area: null, track: [], selected: null, pending: false};
const svg = document.getElementById("map");
const SVGNS = svg.namespaceURI;  // the inline <svg> has the SVG namespace; no URL in the page
const EARTH_R = 6371008.8, RAD = Math.PI / 180, MAX_TRACK = 20000;
const COLOURS = __COLOURS__;
function node(tag, attrs, parent) {
  const e = document.createElementNS(SVGNS, tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}
function scheduleMap() {
  if (mapView.pending) return;
  mapView.pending = true;
  setTimeout(() => { mapView.pending = false; drawMap(); }, 30);
}
function mapAlerts() {
  const out = [];
  for (const v of alerts.values()) {
    const a = v.alert;
    if (!a.position) continue;
    if (mapView.mission !== null && a.mission_id !== mapView.mission) continue;
    if (kind(a) === "discarded" && !document.body.classList.contains("show-discarded")) continue;
    if (!shown(a)) continue;  // a live candidate still settling
    out.push(a);
  }
  return out;
}
function niceLength(m) {
  const p = Math.pow(10, Math.floor(Math.log10(m)));
  for (const f of [5, 2, 1]) if (f * p <= m) return f * p;
  return p;
}
function drawMap() {
  const W = svg.clientWidth, H = svg.clientHeight;
  if (!W || !H) return;
  svg.setAttribute("viewBox", "0 0 " + W + " " + H);
  svg.replaceChildren();
  node("rect", {class: "bg", x: 0, y: 0, width: W, height: H, fill: "#e9eef1"}, svg);
  const shown = mapAlerts();
  const latlon = [];
  for (const v of mapView.area || []) latlon.push(v);
  for (const p of mapView.track) latlon.push([p[1], p[2]]);
  for (const a of shown) latlon.push([a.position.lat, a.position.lon]);
  if (!latlon.length) {
    node("text", {x: W / 2, y: H / 2, "text-anchor": "middle", fill: "#555",
                  "font-size": 15}, svg).textContent = "No positions yet";
    return;
  }
  let minLat = 90, maxLat = -90, minLon = 180, maxLon = -180;
  for (const [la, lo] of latlon) {
    minLat = Math.min(minLat, la); maxLat = Math.max(maxLat, la);
    minLon = Math.min(minLon, lo); maxLon = Math.max(maxLon, lo);
  }
  const lat0 = (minLat + maxLat) / 2, lon0 = (minLon + maxLon) / 2;
  const kx = EARTH_R * RAD * Math.cos(lat0 * RAD), ky = EARTH_R * RAD;
  const local = (la, lo) => [(lo - lon0) * kx, (la - lat0) * ky];
  let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
  const grow = (x, y, r) => {
    x0 = Math.min(x0, x - r); x1 = Math.max(x1, x + r);
    y0 = Math.min(y0, y - r); y1 = Math.max(y1, y + r);
  };
  for (const [la, lo] of latlon) grow(...local(la, lo), 0);
  for (const a of shown) {
    if (kind(a) === "dismissed") grow(...local(a.position.lat, a.position.lon), a.dismiss_radius_m);
  }
  const span = 100;  // metres: never zoom in further than this across
  const mx = (x0 + x1) / 2, my = (y0 + y1) / 2;
  const dx = Math.max(x1 - x0, span), dy = Math.max(y1 - y0, span);
  const pad = 30, scale = Math.min((W - 2 * pad) / dx, (H - 2 * pad) / dy);
  const px = (la, lo) => {
    const [x, y] = local(la, lo);
    return [W / 2 + (x - mx) * scale, H / 2 - (y - my) * scale];
  };
  if (mapView.area && mapView.area.length >= 3) {
    const ring = mapView.area.map(v => px(v[0], v[1]).join(",")).join(" ");
    node("polygon", {class: "area", points: ring,
                     fill: "rgba(55,71,79,0.07)", stroke: "#37474f", "stroke-width": 2,
                     "stroke-dasharray": "8 5"}, svg);
  }
  if (mapView.track.length) {
    const pts = mapView.track.map(p => px(p[1], p[2]));
    node("polyline", {class: "track", points: pts.map(p => p.join(",")).join(" "), fill: "none",
                      stroke: "#1565c0", "stroke-width": 2.5, "stroke-linejoin": "round",
                      "stroke-opacity": 0.8}, svg);
    const [x, y] = pts[pts.length - 1];  // the drone's newest position (no heading known)
    node("circle", {class: "drone", cx: x, cy: y, r: 6, fill: "#0d47a1", stroke: "#fff",
                    "stroke-width": 2}, svg);
  }
  const order = {dismissed: 0, discarded: 1, candidate: 2, alert: 3};
  shown.sort((a, b) => order[kind(a)] - order[kind(b)]);
  for (const a of shown) drawMarker(a, px, scale);
  drawScale(W, H, scale);
  drawNorth(W);
}
function drawMarker(a, px, scale) {
  const k = kind(a);
  const [x, y] = px(a.position.lat, a.position.lon);
  const g = node("g", {class: "marker " + k, "data-alert": a.alert_id}, svg);
  g.style.cursor = "pointer";
  if (k === "dismissed") {
    node("circle", {class: "zone", cx: x, cy: y, r: Math.max(a.dismiss_radius_m * scale, 8),
                    fill: "#9e9e9e", "fill-opacity": 0.35, stroke: "#8d8d8d",
                    "stroke-width": 1.5}, g);
    node("circle", {class: "centre", cx: x, cy: y, r: 5, fill: COLOURS.dismissed}, g);
  } else if (k === "discarded") {
    node("circle", {class: "centre", cx: x, cy: y, r: 7, fill: "none", stroke: "#b08d2a",
                    "stroke-width": 2, "stroke-dasharray": "3 2"}, g);
  } else {
    node("circle", {class: "centre", cx: x, cy: y, r: 9, fill: COLOURS[k], stroke: "#fff",
                    "stroke-width": 2}, g);
    node("text", {x: x + 12, y: y - 10, "font-size": 12, "font-weight": 700, fill: "#1d2733",
                  stroke: "#fff", "stroke-width": 3, "paint-order": "stroke"}, g)
      .textContent = a.short_id || ("T" + a.target_id);
  }
  if (mapView.selected === a.alert_id) {
    node("circle", {class: "ring", cx: x, cy: y, r: 16, fill: "none", stroke: "#1565c0",
                    "stroke-width": 3}, g);
  }
  node("circle", {class: "hit", cx: x, cy: y, r: 22, fill: "#000", "fill-opacity": 0}, g);
  g.addEventListener("click", () => select(a.alert_id, true));
}
function drawScale(W, H, scale) {
  const metres = niceLength((W / 4) / scale), len = metres * scale;
  const x = 14, y = H - 16;
  const g = node("g", {class: "scale"}, svg);
  node("rect", {x: x - 6, y: y - 22, width: len + 12, height: 30, rx: 4, fill: "#fff",
                "fill-opacity": 0.8}, g);
  node("path", {d: "M" + x + " " + (y - 6) + "v6h" + len + "v-6", fill: "none",
                stroke: "#111", "stroke-width": 2}, g);
  node("text", {x: x + len / 2, y: y - 9, "text-anchor": "middle", "font-size": 12,
                fill: "#111"}, g)
    .textContent = metres >= 1000 ? (metres / 1000) + " km" : metres + " m";
}
function drawNorth(W) {
  const x = W - 26, y = 16;
  const g = node("g", {class: "north"}, svg);
  node("polygon", {points: [x, y, x - 9, y + 24, x, y + 18, x + 9, y + 24].join(" "),
                   fill: "#111"}, g);
  node("text", {x: x, y: y + 40, "text-anchor": "middle", "font-size": 13, "font-weight": 700,
                fill: "#111"}, g).textContent = "N";
}
function setMap(m) {
  mapView.mission = m.mission_id;
  mapView.area = m.area;
  mapView.track = m.track || [];
  scheduleMap();
}
function addTrack(m) {
  if (m.mission_id !== mapView.mission) return;
  for (const p of m.track) mapView.track.push(p);
  if (mapView.track.length > MAX_TRACK) mapView.track.splice(0, mapView.track.length - MAX_TRACK);
  scheduleMap();
}
function setArea(m) {
  if (m.mission_id !== mapView.mission) return;
  mapView.area = m.area;
  scheduleMap();
}
if (window.ResizeObserver) new ResizeObserver(scheduleMap).observe(svg);
window.addEventListener("resize", scheduleMap);
"""


def map_js() -> str:
    """The map's script with its marker colours filled in."""
    return MAP_JS.replace("__COLOURS__", json.dumps(MARKER_COLOURS))
