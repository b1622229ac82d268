"""The operator page's alert cards and the operator's actions on them (JavaScript).

A card shows one alert by its *kind* (:func:`kind` in the script): ``alert`` (confirmed, red,
Acknowledge and Dismiss), ``candidate`` ("unconfirmed", amber, Confirm and Dismiss, never a
flash), ``discarded`` (a candidate the system gave up on: hidden unless "show discarded" is on,
Confirm and Dismiss) and ``dismissed`` (grey, who and when, Confirm to change one's mind).
Confirm and Dismiss POST ``{"by": <operator name>}`` to ``/api/alerts/<id>/confirm|dismiss``;
the name is required, and the page asks for it instead of sending an anonymous decision.

A candidate that arrives live is held back for :data:`SETTLE_S` (card, count and map marker):
the controller decides most candidates within about two seconds of their lock (confirmed, it
shows as an alert; discarded, it never shows), so the operator's list holds what is still
waiting instead of a card that appears and vanishes several times a second over clutter.
Candidates already stored when the page opens show at once.
"""

from sarmission.alerts.model import WIDE_RANGE

#: Seconds a live candidate stays off the page while the evidence decides it (the default
#: confirmation waits 2 s: ``ConfirmConfig.min_seen_s``).
SETTLE_S = 3.0

CARDS_JS = (
    f"const SETTLE_MS = {round(SETTLE_S * 1000)};\n"
    f"const WIDE_RANGE = {WIDE_RANGE};\n"
    + r"""
const NAMES = {mavlink_loiter: "loiter", mavlink_roi: "camera ROI",
               mavlink_mission: "mission visit"};
function kind(a) {
  if (a.decision === "dismissed") return "dismissed";
  if (a.tier === "confirmed") return "alert";
  if (a.discarded) return "discarded";
  return "candidate";
}
const settling = new Set();  // ids of live candidates held back for SETTLE_MS
function shown(a) { return !(kind(a) === "candidate" && settling.has(a.alert_id)); }
function settle(a) {
  settling.add(a.alert_id);
  setTimeout(() => {
    settling.delete(a.alert_id);
    const entry = alerts.get(a.alert_id);
    if (entry) entry.card.dataset.settling = "0";
    counts();
    scheduleMap();
  }, SETTLE_MS);
}
async function post(a, verb, body) {
  const r = await fetch("/api/alerts/" + encodeURIComponent(a.alert_id) + "/" + verb, {
    method: "POST", headers: {"Content-Type": "application/json"},
    body: JSON.stringify(body)});
  if (!r.ok) throw new Error(await refusal(r));
  return r.json();
}
async function acknowledge(a, button, side) {
  button.disabled = true;
  try {
    upsert(await post(a, "ack", {by: operator.value.trim() || "operator"}), false);
  } catch (e) {
    button.disabled = false;
    side.appendChild(el("div", "ackerr", "not acknowledged: " + e.message));
  }
}
async function decide(a, verb, button, side) {
  const by = operator.value.trim();
  if (!by) {
    side.appendChild(el("div", "ackerr", "enter your name in the Operator field first"));
    operator.focus();
    return;
  }
  button.disabled = true;
  try {
    upsert(await post(a, verb, {by: by}), false);
  } catch (e) {
    button.disabled = false;
    side.appendChild(el("div", "ackerr", "not " + verb + "ed: " + e.message));
  }
}
function button(cls, text, action) {
  const b = el("button", cls, text);
  b.type = "button";
  b.addEventListener("click", (e) => { e.stopPropagation(); action(b); });
  return b;
}
function render(a) {
  const k = kind(a);
  const card = el("article", "alert");
  card.dataset.alertId = a.alert_id;
  card.dataset.acknowledged = a.acknowledged ? "1" : "0";
  card.dataset.kind = k;
  card.dataset.tier = a.tier;
  card.dataset.decision = a.decision || "";
  card.dataset.settling = shown(a) ? "0" : "1";
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
  if (a.confidence !== null && a.confidence !== undefined) {  // calibrated: what the score means
    const pct = (p) => Math.min(99, Math.max(1, Math.round(100 * p)));
    const range = a.confidence_range;
    const wide = range && range[1] - range[0] >= WIDE_RANGE;
    let text = pct(a.confidence) + " % likely a person";
    if (wide) text += ", between " + pct(range[0]) + " and " + pct(range[1]) + " %";
    const low = (range ? pct(range[1]) : pct(a.confidence)) < 20;
    const likely = el("span", "likely" + (low ? " low" : "") + (wide ? " wide" : ""), text);
    likely.title = wide
      ? "still learning this mission: the range narrows as you confirm or dismiss alerts"
      : "calibrated by your decisions on this mission's alerts";
    title.appendChild(likely);
  }
  title.appendChild(el("span", "target", "target " + a.target_id
    + (a.short_id ? " \u00b7 " + a.short_id : "")));
  const badges = {candidate: "Unconfirmed", discarded: "Discarded", dismissed: "Dismissed"};
  if (badges[k]) title.appendChild(el("span", "badge " + k, badges[k]));
  card.appendChild(title);
  const where = el("div", "where");
  if (a.position) {
    const full = a.position.lat + ", " + a.position.lon;
    const c = el("button", "coords", a.position.lat.toFixed(6) + ", " + a.position.lon.toFixed(6));
    c.title = "Click to copy " + full;
    c.addEventListener("click", async (e) => {
      e.stopPropagation();
      await copyText(full);
      c.classList.add("copied");
      setTimeout(() => c.classList.remove("copied"), 900);
    });
    where.appendChild(c);
    if (a.error_m !== null) {
      where.appendChild(el("span", "err", "\u00b1" + Math.max(1, Math.round(a.error_m)) + " m"));
    }
    if (a.position_time && a.position_time > a.lock_time + 0.5) {  // refined since the lock
      where.appendChild(el("span", "asof", "as of " + utc(a.position_time)));
    }
    if (a.drift && a.drift.speed_m_s > 0) {  // where a drifting swimmer is heading
      const course = String(Math.round(a.drift.course_deg) % 360).padStart(3, "0");
      where.appendChild(el("span", "drift",
        "drifting " + a.drift.speed_m_s.toFixed(1) + " m/s to " + course + "\u00b0"));
    }
  } else {
    const note = a.position_note ? ": " + a.position_note : "";
    where.appendChild(el("span", "nopos", "Position unknown" + note));
  }
  card.appendChild(where);
  card.appendChild(stateLine(a, k));
  card.appendChild(metaLine(a));
  card.appendChild(actions(a, k));
  card.addEventListener("click", () => select(a.alert_id, false));
  return card;
}
function stateLine(a, k) {
  const state = el("div", "state");
  const parts = [];
  if (k === "candidate") parts.push("Unconfirmed: waiting for evidence or an operator");
  if (a.discarded) parts.push("Discarded by the system: " + a.discarded);
  else if (a.tier === "confirmed" && a.evidence) parts.push("Confirmed: " + a.evidence);
  if (a.decision) {
    parts.push((a.decision === "dismissed" ? "\u2715 Dismissed" : "\u2713 Confirmed")
      + " by " + a.decided_by + " at " + utc(a.decided_at));
  }
  state.textContent = parts.join(" \u00b7 ");
  return state;
}
function metaLine(a) {
  const meta = el("div", "meta");
  const when = el("span", "when");
  when.dataset.t = a.lock_time;
  when.textContent = utc(a.lock_time) + " \u00b7 " + age(a.lock_time);
  meta.appendChild(when);
  meta.appendChild(document.createTextNode(" \u00b7 frame " + a.frame_index + " "));
  const sent = a.sent || {};
  if (sent.mavlink) {
    meta.appendChild(el("span", "chip", "STATUSTEXT sent " + sent.mavlink.count
      + "\u00d7 (no acknowledgement)"));
  }
  for (const ch of Object.keys(a.delivered)) {
    if (NAMES[ch]) meta.appendChild(el("span", "chip", NAMES[ch] + " acknowledged"));
  }
  for (const [ch, r] of Object.entries(a.refused || {})) {
    if (NAMES[ch]) {
      meta.appendChild(el("span", "chip refused", NAMES[ch] + " refused: " + r.reason));
    }
  }
  if (sent.cot) meta.appendChild(el("span", "chip", "TAK sent " + sent.cot.count + "\u00d7"));
  return meta;
}
function actions(a, k) {
  const side = el("div", "side");
  if (k === "alert") {
    if (a.acknowledged) {
      side.appendChild(el("div", "acked", "\u2713 Acknowledged"));
      side.appendChild(el("div", "meta", "by " + a.ack_by + " at " + utc(a.ack_time)));
    } else {
      side.appendChild(button("ack", "Acknowledge", (b) => acknowledge(a, b, side)));
    }
  } else {
    side.appendChild(button("confirm", "Confirm", (b) => decide(a, "confirm", b, side)));
  }
  if (k !== "dismissed") {
    side.appendChild(button("dismiss", "Dismiss", (b) => decide(a, "dismiss", b, side)));
  }
  return side;
}
function upsert(a, fresh) {
  const old = alerts.get(a.alert_id);
  if (!old && fresh && kind(a) === "candidate") settle(a);  // before render: it reads settling
  const card = render(a);
  if (old) {
    if (old.card.classList.contains("highlight")) card.classList.add("highlight");
    old.card.replaceWith(card);
    // a candidate the system has just confirmed is news: it flashes like a new alert
    if (fresh && kind(a) === "alert" && kind(old.alert) !== "alert") card.classList.add("fresh");
  } else {
    list.prepend(card);
    if (fresh && kind(a) === "alert") card.classList.add("fresh");
  }
  alerts.set(a.alert_id, {alert: a, card: card});
  counts();
  scheduleMap();
}
function counts() {
  let total = 0, unacked = 0, review = 0;
  for (const v of alerts.values()) {
    const k = kind(v.alert);
    if (k === "alert") { total++; if (!v.alert.acknowledged) unacked++; }
    if (k === "candidate" && shown(v.alert)) review++;
  }
  document.getElementById("total").textContent = total;
  document.getElementById("unacked").textContent = unacked;
  document.getElementById("review").textContent = review;
  taught();
  document.getElementById("empty").hidden = alerts.size > 0;
  const n = unacked + review;
  document.title = (n ? "(" + n + ") " : "") + "SAR alerts";
}
function taught() {  // the decisions the newest mission's confidence has learnt from
  let newest = null;
  for (const v of alerts.values()) {
    if (!newest || v.alert.lock_time > newest.lock_time) newest = v.alert;
  }
  let rated = 0, decided = 0;
  for (const v of alerts.values()) {
    const a = v.alert;
    if (a.mission_id !== newest.mission_id || a.evidence_logit == null) continue;
    rated++;
    if (a.decision) decided++;
  }
  document.getElementById("taught").hidden = rated === 0;
  document.getElementById("decisions").textContent = decided;
}
function select(id, fromMap) {
  mapView.selected = id;
  for (const v of alerts.values()) v.card.classList.toggle("highlight", v.alert.alert_id === id);
  const entry = alerts.get(id);
  if (fromMap && entry) entry.card.scrollIntoView({block: "nearest"});
  scheduleMap();
}
"""
)
