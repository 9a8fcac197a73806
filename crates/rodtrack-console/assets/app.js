// rodtrack console: live view, plots and calibration. Plain canvas drawing, no libraries.
'use strict';

// The session token the console put in the page: sent with every state-changing request.
const TOKEN = (document.querySelector('meta[name="rodtrack-token"]') || {}).content || '';

const STATUS = ['ok', 'not_found', 'occluded', 'out_of_view', 'predicted', 'lost', 'bad_frame', 'conflict'];
const STATUS_COLOUR = {
  ok: '#3fd16b', not_found: '#ff5555', occluded: '#ffa931', out_of_view: '#8a8f96',
  predicted: '#58a6ff', lost: '#c678dd', bad_frame: '#c678dd', conflict: '#ff79c6',
};

// An angle as a label: signed degrees in (-180, 180], so that a rod at 0 rad whose angle
// reads just below 2 pi shows 0°, not 360°.
function angleLabel(rad) {
  let d = Math.round(rad * 180 / Math.PI) % 360;
  if (d > 180) d -= 360;
  if (d <= -180) d += 360;
  if (Object.is(d, -0)) d = 0;
  return `${d}°`;
}

// The text beside a rod in the live view.
function overlayText(o) {
  return `rod ${o.rod} ${o.status}` + (o.status === 'ok' ? ` ${o.position_mm.toFixed(1)} mm ${angleLabel(o.angle_rad)}` : (o.reason ? ` (${o.reason})` : ''));
}
const ROD_COLOUR = ['#e6194b', '#3cb44b', '#ffe119', '#4e8cff', '#f58231', '#bf5af2', '#42d4f4',
  '#f032e6', '#bfef45', '#fabed4', '#469990', '#dcbeff'];
const KEEP_S = 25;

// State visible to tests.
const rt = window.rodtrack = {
  rows: 0, frames: 0, plotDraws: 0, lastT: 0, connected: false,
  series: new Map(), // "cam:rod" -> {t: [], pos: [], ang: []}
  cams: new Map(),   // camera -> {canvas, ctx, img, header}
  calib: null, calFrame: null,
  overlayText, angleLabel,
};

const $ = (id) => document.getElementById(id);

// ------------------------------------------------------------------------------ tabs
function showTab(name) {
  $('live').hidden = name !== 'live';
  $('calib').hidden = name !== 'calib';
  $('tab-live').classList.toggle('on', name === 'live');
  $('tab-calib').classList.toggle('on', name === 'calib');
  if (name === 'calib') refreshCalib(true);
}
$('tab-live').onclick = () => showTab('live');
$('tab-calib').onclick = () => showTab('calib');

// ------------------------------------------------------------------------ websocket
function connect() {
  const ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => { rt.connected = true; $('conn').textContent = 'live'; $('conn').classList.remove('bad'); };
  ws.onclose = () => {
    rt.connected = false; $('conn').textContent = 'disconnected'; $('conn').classList.add('bad');
    setTimeout(connect, 1000);
  };
  ws.onmessage = (ev) => {
    if (typeof ev.data === 'string') {
      const m = JSON.parse(ev.data);
      if (m.t === 'rows') addRows(m.rows);
      else if (m.t === 'stats') showStats(m);
      else if (m.t === 'ball') showBall(m);
    } else {
      const f = parseFrame(ev.data);
      if (f) showFrame(f);
    }
  };
}

// A frame message: [u32 LE n][n bytes JSON header][pixels].
function parseFrame(buf) {
  const dv = new DataView(buf);
  const n = dv.getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 4, n)));
  const px = new Uint8Array(buf, 4 + n);
  const img = new ImageData(header.pw, header.ph);
  const d = img.data;
  const c = header.channels;
  for (let i = 0, j = 0; i < header.pw * header.ph; i++, j += c) {
    const k = 4 * i;
    if (c === 1) { d[k] = d[k + 1] = d[k + 2] = px[j]; } else { d[k] = px[j]; d[k + 1] = px[j + 1]; d[k + 2] = px[j + 2]; }
    d[k + 3] = 255;
  }
  return { header, img };
}

// ---------------------------------------------------------------------- live frames
function camPanel(cam, w, h) {
  let p = rt.cams.get(cam);
  if (p && p.canvas.width === w && p.canvas.height === h) return p;
  if (!p) {
    const div = document.createElement('div');
    div.className = 'cam';
    div.innerHTML = `<div class="title" id="cam-title-${cam}">camera ${cam}</div>`;
    const canvas = document.createElement('canvas');
    canvas.id = `cam-${cam}`;
    div.appendChild(canvas);
    $('cams').appendChild(div);
    p = { canvas, ctx: canvas.getContext('2d') };
    rt.cams.set(cam, p);
  }
  p.canvas.width = w; p.canvas.height = h;
  return p;
}

// Live previews narrower than this (decimated copies) are drawn enlarged, so that the
// overlays stay sharp.
const LIVE_DRAW_WIDTH = 720;
let liveScratch = null;

function showFrame(f) {
  const h = f.header;
  const up = Math.max(1, Math.round(LIVE_DRAW_WIDTH / h.pw));
  const p = camPanel(h.camera, h.pw * up, h.ph * up);
  if (up === 1) {
    p.ctx.putImageData(f.img, 0, 0);
  } else {
    if (!liveScratch) liveScratch = document.createElement('canvas');
    liveScratch.width = h.pw; liveScratch.height = h.ph;
    liveScratch.getContext('2d').putImageData(f.img, 0, 0);
    p.ctx.imageSmoothingEnabled = true;
    p.ctx.drawImage(liveScratch, 0, 0, h.pw * up, h.ph * up);
  }
  p.header = h;
  const s = up / h.factor;
  const X = (q) => (q[0] + 0.5) * s, Y = (q) => (q[1] + 0.5) * s;
  for (const o of h.overlays) drawOverlay(p.ctx, o, X, Y);
  const ok = h.overlays.filter((o) => o.status === 'ok').length;
  $(`cam-title-${h.camera}`).textContent =
    `camera ${h.camera}  frame ${h.frame_id}  t ${h.timestamp_s.toFixed(3)} s  ${h.width}x${h.height}  rods ok ${ok}/${h.overlays.length}`;
  rt.frames++;
}

function drawOverlay(ctx, o, X, Y) {
  const col = STATUS_COLOUR[o.status] || '#fff';
  ctx.save();
  ctx.lineWidth = 1;
  ctx.strokeStyle = col; ctx.globalAlpha = 0.45;
  ctx.beginPath();
  o.line_px.forEach((q, i) => (i ? ctx.lineTo(X(q), Y(q)) : ctx.moveTo(X(q), Y(q))));
  ctx.stroke();
  ctx.globalAlpha = 1;
  const m = o.marker;
  let label = o.line_px.length ? o.line_px[0] : [0, 0];
  if (m) {
    ctx.setLineDash([3, 3]);
    ctx.beginPath(); ctx.moveTo(X(m.marker_px[0]), Y(m.marker_px[0])); ctx.lineTo(X(m.marker_px[1]), Y(m.marker_px[1])); ctx.stroke();
    ctx.setLineDash([]);
    ctx.lineWidth = 4;
    ctx.beginPath(); ctx.moveTo(X(m.barcode_px[0]), Y(m.barcode_px[0])); ctx.lineTo(X(m.barcode_px[1]), Y(m.barcode_px[1])); ctx.stroke();
    ctx.lineWidth = 2; ctx.strokeStyle = '#42d4f4';
    ctx.beginPath(); ctx.moveTo(X(m.phase_window_px[0]), Y(m.phase_window_px[0])); ctx.lineTo(X(m.phase_window_px[1]), Y(m.phase_window_px[1])); ctx.stroke();
    ctx.lineWidth = 1; ctx.strokeStyle = col;
    for (const b of m.bits) {
      ctx.beginPath(); ctx.arc(X(b.centre_px), Y(b.centre_px), 3, 0, 2 * Math.PI);
      ctx.fillStyle = b.black ? '#000' : '#fff'; ctx.fill(); ctx.stroke();
    }
    label = m.barcode_px[0];
  }
  ctx.font = '11px monospace';
  const text = overlayText(o);
  const tx = Math.min(X(label) + 8, ctx.canvas.width - ctx.measureText(text).width - 2), ty = Math.max(Y(label), 10);
  ctx.fillStyle = 'rgba(0,0,0,0.6)'; ctx.fillRect(tx - 2, ty - 10, ctx.measureText(text).width + 4, 13);
  ctx.fillStyle = col; ctx.fillText(text, tx, ty);
  ctx.restore();
}

// -------------------------------------------------------------------------- rows
function addRows(rows) {
  for (const r of rows) {
    const key = `${r[1]}:${r[2]}`;
    let s = rt.series.get(key);
    if (!s) { s = { cam: r[1], rod: r[2], t: [], pos: [], ang: [], st: [], kn: [] }; rt.series.set(key, s); updateSources(); }
    s.t.push(r[0]); s.pos.push(r[3]); s.ang.push(r[4]); s.st.push(r[7]); s.kn.push(r[8]);
    s.last = { status: r[7], known: r[8] === 1, unwrapped: r[4], angle: r[5] };
    if (r[0] > rt.lastT) rt.lastT = r[0];
  }
  rt.rows += rows.length;
  for (const s of rt.series.values()) {
    // Trim old samples in blocks (cheap amortised).
    let k = 0;
    while (k < s.t.length && s.t[k] < rt.lastT - KEEP_S) k++;
    if (k > 1000 || (k > 0 && k === s.t.length)) { s.t.splice(0, k); s.pos.splice(0, k); s.ang.splice(0, k); s.st.splice(0, k); s.kn.splice(0, k); }
    // The clock went back (the demo loops): start over.
    if (s.t.length && s.t[s.t.length - 1] < rt.lastT - KEEP_S) { s.t = []; s.pos = []; s.ang = []; s.st = []; s.kn = []; }
  }
  const last = rows.length ? rows[rows.length - 1][0] : rt.lastT;
  if (last < rt.lastT - 1) { // loop restart: clear everything
    rt.lastT = last;
    for (const s of rt.series.values()) { s.t = []; s.pos = []; s.ang = []; s.st = []; s.kn = []; }
  }
}

function updateSources() {
  const sel = $('source');
  const cams = [...new Set([...rt.series.values()].map((s) => s.cam))].sort((a, b) => a - b);
  const want = cams.map((c) => (c < 0 ? 'fused' : `camera ${c}`));
  const have = [...sel.options].map((o) => o.text);
  if (want.join() === have.join()) return;
  const prev = sel.value;
  sel.innerHTML = '';
  cams.forEach((c) => { const o = document.createElement('option'); o.value = c; o.text = c < 0 ? 'fused' : `camera ${c}`; sel.appendChild(o); });
  sel.value = cams.includes(Number(prev)) && prev !== '' ? prev : String(cams[0]);
}

function drawPlot(canvas, field, label, unit, cam, win) {
  const ctx = canvas.getContext('2d');
  const W = canvas.width, H = canvas.height, L = 60, R = 10, T = 16, B = 18;
  ctx.fillStyle = '#0d0f12'; ctx.fillRect(0, 0, W, H);
  const t1 = rt.lastT, t0 = t1 - win;
  const list = [...rt.series.values()].filter((s) => s.cam === cam).sort((a, b) => a.rod - b.rod);
  let lo = Infinity, hi = -Infinity;
  const ranges = list.map((s) => {
    let i = s.t.length; while (i > 0 && s.t[i - 1] >= t0) i--;
    for (let k = i; k < s.t.length; k++) if (s.st[k] === 0) { const v = s[field][k]; if (v < lo) lo = v; if (v > hi) hi = v; }
    return i;
  });
  if (!(hi > lo)) { lo = (isFinite(lo) ? lo : 0) - 1; hi = lo + 2; }
  const pad = 0.05 * (hi - lo); lo -= pad; hi += pad;
  const x = (t) => L + (t - t0) / win * (W - L - R);
  const y = (v) => T + (hi - v) / (hi - lo) * (H - T - B);
  ctx.strokeStyle = '#2a3038'; ctx.fillStyle = '#98a2ad'; ctx.font = '11px monospace'; ctx.lineWidth = 1;
  for (let k = 0; k <= 4; k++) {
    const v = lo + (hi - lo) * k / 4, yy = y(v);
    ctx.beginPath(); ctx.moveTo(L, yy); ctx.lineTo(W - R, yy); ctx.stroke();
    ctx.fillText(v.toFixed(Math.abs(hi - lo) < 10 ? 2 : 0), 4, yy + 4);
  }
  for (let s = Math.ceil(t0); s <= t1; s++) { const xx = x(s); ctx.beginPath(); ctx.moveTo(xx, T); ctx.lineTo(xx, H - B); ctx.stroke(); ctx.fillText(`${s}s`, xx + 2, H - 5); }
  ctx.fillStyle = '#dde2e8'; ctx.fillText(`${label} (${unit})`, L, 12);
  list.forEach((s, j) => {
    const i0 = ranges[j], n = s.t.length - i0;
    if (n <= 0) return;
    const step = Math.max(1, Math.floor(n / (W - L - R)));  // decimate for drawing
    // Two passes: the samples whose turn count is known in the rod's colour, then (angle
    // plot) those whose count is unknown in grey: their unwrapped angle may be off by turns.
    for (const known of field === 'ang' ? [true, false] : [null]) {
      ctx.strokeStyle = known === false ? '#6b7280' : ROD_COLOUR[s.rod % ROD_COLOUR.length];
      ctx.lineWidth = 1.3;
      ctx.setLineDash(known === false ? [4, 3] : []);
      ctx.beginPath();
      let pen = false;
      for (let k = i0; k < s.t.length; k += step) {
        if ((s.st[k] !== 0 && s.st[k] !== 4) || (known !== null && (s.kn[k] === 1) !== known)) { pen = false; continue; }
        const xx = x(s.t[k]), yy = y(s[field][k]);
        if (pen) ctx.lineTo(xx, yy); else ctx.moveTo(xx, yy);
        pen = true;
      }
      ctx.stroke();
    }
    ctx.setLineDash([]);
  });
}

function drawPlots() {
  const sel = $('source');
  if (sel.value !== '' && !$('live').hidden) {
    const cam = Number(sel.value), win = Number($('window').value);
    drawPlot($('plot-pos'), 'pos', 'position', 'mm', cam, win);
    drawPlot($('plot-ang'), 'ang', 'angle, unwrapped', 'rad', cam, win);
    const rods = [...rt.series.values()].filter((s) => s.cam === cam).map((s) => s.rod).sort((a, b) => a - b);
    const leg = rods.map((r) => `<span style="color:${ROD_COLOUR[r % ROD_COLOUR.length]}">rod ${r}</span>`).join('');
    if ($('legend').innerHTML !== leg) $('legend').innerHTML = leg;
    showTurns(cam);
    rt.plotDraws++;
  }
  setTimeout(() => requestAnimationFrame(drawPlots), 50);
}

// The turn count of rod `rod` of source `cam` as its last row gave it: {known, turns, status}
// (turns: the whole turn of the unwrapped angle), or null before any row.
function turnsOf(cam, rod) {
  const s = rt.series.get(`${cam}:${rod}`);
  if (!s || !s.last) return null;
  const l = s.last;
  return { known: l.known, status: STATUS[l.status] || '?', turns: Math.round((l.unwrapped - l.angle) / (2 * Math.PI)) };
}
rt.turnsOf = turnsOf;

// Per rod of the plotted source: its whole turn, or a "turns ?" badge while the count is
// unknown (the unwrapped angle may be off by whole turns until it is re-anchored).
function showTurns(cam) {
  const rods = [...rt.series.values()].filter((s) => s.cam === cam).map((s) => s.rod).sort((a, b) => a - b);
  const html = rods.map((rod) => {
    const t = turnsOf(cam, rod);
    if (!t) return '';
    const value = t.status === 'ok' || t.status === 'predicted';
    if (value && !t.known) return `<span class="turns unknown" data-rod="${rod}" title="the turn count may have slipped: re-anchor it">rod ${rod} turns ?</span>`;
    if (!value) return `<span class="turns idle" data-rod="${rod}">rod ${rod} ${t.status}</span>`;
    return `<span class="turns" data-rod="${rod}">rod ${rod} turn ${t.turns}</span>`;
  }).join('');
  if ($('turns').innerHTML !== html) $('turns').innerHTML = html;
}

$('ra-go').onclick = async () => {
  const rod = $('ra-rod').value.trim(), turns = $('ra-turns').value.trim();
  const body = { rod: rod === '' ? null : Number(rod), turns: turns === '' ? null : Number(turns) };
  try {
    await api('POST', '/api/reanchor', body);
    $('ra-msg').textContent = `rod ${body.rod}: turn count set to ${body.turns}`;
    $('ra-msg').classList.remove('err');
  } catch (e) { $('ra-msg').textContent = e.message; $('ra-msg').classList.add('err'); }
};

function showStats(m) {
  const s = m.stats, o = m.overhead;
  let text = '';
  if (s) {
    text += `frames ${s.frames}  ${s.fps.toFixed(1)} frame sets/s  ${s.frame_time_us.toFixed(0)} us/frame set  dropped ${s.dropped_frames}  bad ${s.bad_frames}`;
    if (s.frames > 0 && s.frame_time_us > 0) {
      const share = 100 * (o.total_ns / 1000) / (s.frames * s.frame_time_us);
      text += `\nconsole: ${o.calls} publish calls, ${(o.total_ns / Math.max(1, o.calls)).toFixed(0)} ns mean, ${(o.max_ns / 1000).toFixed(0)} us max, ${share.toFixed(2)} % of tracking time`;
    }
  } else {
    text = `cameras ${m.cameras.map((c) => c.index).join(', ') || 'none'}`;
  }
  if (m.remote) text += remoteText(m.remote);
  $('stats').textContent = text;
  $('reanchor').hidden = !m.session;
  if (m.events) showEvents(m.events);
  rt.stats = m;
}

// The remote nodes of a camera network (`rodtrack console --subscribe zenoh`), a line each.
function remoteText(r) {
  let t = '';
  for (const n of r.nodes) {
    const s = n.status || {};
    let line = `\n${n.node}: ${n.silent ? `SILENT ${n.age_s.toFixed(0)} s` : (s.state || 'running')}`;
    if (Array.isArray(s.cameras)) {
      line += `  sets complete ${s.sets_complete} incomplete ${s.sets_incomplete}  cameras ` +
        s.cameras.map((c) => `${c.name} ${c.state}`).join(', ');
    } else {
      const fps = typeof s.frames_per_s === 'number' ? s.frames_per_s.toFixed(1) : '-';
      line += `  frame ${s.frame ?? '-'}  ${fps} fps  dropped ${s.dropped ?? 0}  bad ${s.bad ?? 0}  publish errors ${s.publish_errors ?? 0}`;
    }
    t += line;
  }
  if (r.malformed > 0) t += `\nmalformed messages: ${r.malformed} (first: ${r.first_errors[0]})`;
  return t;
}

// One event as a line of text (the `--events-out` object's fields).
function eventText(e) {
  const at = `${e.timestamp_s.toFixed(2)} s`;
  switch (e.event) {
    case 'goal': return `${at} goal for ${e.side.toUpperCase()} (${e.score[0]} : ${e.score[1]})`;
    case 'shot': return `${at} shot ${(e.speed_mm_s / 1000).toFixed(1)} m/s rod ${e.rod === null ? '?' : e.rod}`;
    case 'ball_out': return `${at} ball out`;
    case 'ball_stopped': return `${at} ball stopped`;
    default: return `${at} ${e.event}`;
  }
}

// The ball's running score and its last events, newest first.
function showEvents(ev) {
  const score = `${ev.score[0]} : ${ev.score[1]}`;
  if ($('score').textContent !== score) $('score').textContent = score;
  const html = ev.last.length === 0 ? 'none yet' : ev.last.slice().reverse()
    .map((e) => `<span class="${e.event}">${eventText(e)}</span>`).join(' · ');
  if ($('events').innerHTML !== html) $('events').innerHTML = html;
}

// The ball on a top view of the field (table frame: x along the table, goal A on the left;
// y across, up on the page), its trail of the last second, its status and speed.
function showBall(b) {
  const cv = $('field'), g = cv.getContext('2d');
  const [len, wid] = b.field_mm, pad = 8;
  const k = Math.min((cv.width - 2 * pad) / len, (cv.height - 2 * pad) / wid);
  const px = (x) => cv.width / 2 + x * k, py = (y) => cv.height / 2 - y * k;
  g.clearRect(0, 0, cv.width, cv.height);
  g.strokeStyle = '#3b444e'; g.lineWidth = 1;
  g.strokeRect(px(-len / 2), py(wid / 2), len * k, wid * k);
  g.beginPath(); g.moveTo(px(0), py(wid / 2)); g.lineTo(px(0), py(-wid / 2)); g.stroke();
  // The trail, oldest first; null where the ball was lost breaks it.
  g.strokeStyle = '#7fa7d6'; g.beginPath();
  let pen = false, points = 0;
  for (const p of b.trail) {
    if (!p) { pen = false; continue; }
    if (pen) g.lineTo(px(p[0]), py(p[1])); else g.moveTo(px(p[0]), py(p[1]));
    pen = true; points++;
  }
  g.stroke();
  const seen = b.status === 'ok' || b.status === 'predicted';
  if (seen) {
    g.fillStyle = b.status === 'ok' ? '#f0a030' : '#8a6a40';
    g.beginPath(); g.arc(px(b.x_mm), py(b.y_mm), 4, 0, 2 * Math.PI); g.fill();
  }
  cv.dataset.trail = String(points);
  const text = seen
    ? `${(b.speed_mm_s / 1000).toFixed(2)} m/s at (${b.x_mm.toFixed(0)}, ${b.y_mm.toFixed(0)}) mm ${b.status}`
    : b.status;
  if ($('ball').textContent !== text) $('ball').textContent = text;
  rt.ball = b;
}

// ------------------------------------------------------------------- calibration
async function api(method, path, body) {
  const headers = { 'X-Rodtrack-Token': TOKEN };
  if (body) headers['Content-Type'] = 'application/json';
  const r = await fetch(path, { method, headers, body: body ? JSON.stringify(body) : undefined });
  const j = await r.json();
  if (!r.ok) throw new Error(j.error || r.statusText);
  return j;
}

function calMsg(t) { $('cal-msg').textContent = t; }

function curCam() {
  if (!rt.calib) return null;
  return rt.calib.cameras.find((c) => c.index === Number($('cal-cam').value)) || null;
}

function setCalib(state, reloadFrame) {
  const prevFrame = curCam() && curCam().frozen ? curCam().frozen.frame_id : null;
  rt.calib = state;
  const camSel = $('cal-cam');
  const ids = [...new Set([...state.cameras.map((c) => c.index), ...state.live_cameras])].sort((a, b) => a - b);
  const prev = camSel.value;
  camSel.innerHTML = ids.map((i) => `<option value="${i}">camera ${i}</option>`).join('');
  if (ids.map(String).includes(prev)) camSel.value = prev;
  const cam = curCam();
  const rodSel = $('cal-rod');
  const prevRod = rodSel.value;
  rodSel.innerHTML = cam ? cam.inputs.rods.map((r) => `<option value="${r.rod}">rod ${r.rod} (${r.path_points_px.length} points)</option>`).join('') : '';
  if (cam && cam.inputs.rods.some((r) => String(r.rod) === prevRod)) rodSel.value = prevRod;
  const rod = curRod();
  if (rod) {
    $('ref-pos').value = rod.reference.position_mm; $('ref-ang').value = rod.reference.angle_rad;
    $('trav0').value = rod.travel_mm[0]; $('trav1').value = rod.travel_mm[1];
  }
  if (cam && cam.inputs.rods.length) $('new-rod').value = Math.max(...cam.inputs.rods.map((r) => r.rod)) + 1;
  showPoses(rod);
  showResiduals();
  const nowFrame = cam && cam.frozen ? cam.frozen.frame_id : null;
  if (cam && cam.frozen && (reloadFrame || nowFrame !== prevFrame || !rt.calFrame || rt.calFrame.header.camera !== cam.index)) loadCalFrame(cam.index);
  else drawCal();
}

function curRod() {
  const cam = curCam();
  if (!cam) return null;
  return cam.inputs.rods.find((r) => String(r.rod) === $('cal-rod').value) || null;
}

async function refreshCalib(reload) {
  try { setCalib(await api('GET', '/api/calib'), reload); } catch (e) { calMsg(e.message); }
}

async function loadCalFrame(cam) {
  const r = await fetch(`/api/calib/${cam}/frame`);
  if (!r.ok) { rt.calFrame = null; drawCal(); return; }
  rt.calFrame = parseFrame(await r.arrayBuffer());
  const c = $('cal-canvas');
  c.width = rt.calFrame.header.pw; c.height = rt.calFrame.header.ph;
  drawCal();
}

function drawCal() {
  const c = $('cal-canvas'), ctx = c.getContext('2d');
  const cam = curCam();
  ctx.fillStyle = '#0d0f12'; ctx.fillRect(0, 0, c.width, c.height);
  if (!rt.calFrame || !cam) {
    ctx.fillStyle = '#98a2ad'; ctx.font = '16px sans-serif';
    ctx.fillText('no frozen frame: press "Freeze frame"', 20, 30);
    return;
  }
  ctx.putImageData(rt.calFrame.img, 0, 0);
  const f = rt.calFrame.header.factor;
  const sel = $('cal-rod').value;
  for (const r of cam.inputs.rods) {
    const col = ROD_COLOUR[r.rod % ROD_COLOUR.length];
    const on = String(r.rod) === sel;
    ctx.strokeStyle = col; ctx.fillStyle = col; ctx.lineWidth = on ? 2 : 1;
    const pts = r.path_points_px.map((p) => [(p[0] + 0.5) / f, (p[1] + 0.5) / f]);
    pts.forEach((p) => { ctx.beginPath(); ctx.arc(p[0], p[1], on ? 5 : 3, 0, 2 * Math.PI); ctx.stroke(); ctx.beginPath(); ctx.moveTo(p[0] - 8, p[1]); ctx.lineTo(p[0] + 8, p[1]); ctx.moveTo(p[0], p[1] - 8); ctx.lineTo(p[0], p[1] + 8); ctx.stroke(); });
    if (pts.length) { ctx.font = '12px monospace'; ctx.fillText(`rod ${r.rod}`, pts[0][0] + 8, pts[0][1] - 6); }
  }
  ctx.fillStyle = '#fff'; ctx.font = '12px monospace';
  ctx.fillText(`camera ${cam.index} frozen frame ${rt.calFrame.header.frame_id}`, 6, 14);
}

$('cal-canvas').addEventListener('click', async (e) => {
  const c = $('cal-canvas');
  const cam = curCam(), rod = curRod();
  if (!rt.calFrame || !cam) return;
  if (!rod) { calMsg('add a rod first'); return; }
  const rect = c.getBoundingClientRect();
  const cx = (e.clientX - rect.left) * c.width / rect.width;
  const cy = (e.clientY - rect.top) * c.height / rect.height;
  const f = rt.calFrame.header.factor;
  const x = cx * f - 0.5, y = cy * f - 0.5;
  try { setCalib(await api('POST', `/api/calib/${cam.index}/rods/${rod.rod}/points`, { x, y })); calMsg(`rod ${rod.rod}: point (${x.toFixed(1)}, ${y.toFixed(1)})`); } catch (err) { calMsg(err.message); }
});

$('cal-cam').onchange = () => { rt.calFrame = null; setCalib(rt.calib, true); };
$('cal-rod').onchange = () => setCalib(rt.calib, false);
$('freeze').onclick = async () => {
  const cam = Number($('cal-cam').value);
  try {
    await api('POST', `/api/calib/${cam}/freeze`);
    calMsg('freezing...');
    for (let i = 0; i < 50; i++) {
      await new Promise((r) => setTimeout(r, 100));
      const st = await api('GET', '/api/calib');
      const c = st.cameras.find((x) => x.index === cam);
      if (c && !c.freeze_pending && c.frozen) { setCalib(st, true); calMsg(`frozen frame ${c.frozen.frame_id}`); return; }
    }
    calMsg('no frame arrived');
  } catch (e) { calMsg(e.message); }
};
$('add-rod').onclick = async () => {
  const cam = curCam(); if (!cam) { calMsg('freeze a frame first'); return; }
  const rod = Number($('new-rod').value);
  try { const st = await api('POST', `/api/calib/${cam.index}/rods`, { rod, travel_mm: [Number($('trav0').value), Number($('trav1').value)] }); $('cal-rod').value = String(rod); setCalib(st); $('cal-rod').value = String(rod); setCalib(st); } catch (e) { calMsg(e.message); }
};
$('del-rod').onclick = async () => {
  const cam = curCam(), rod = curRod(); if (!cam || !rod) return;
  try { setCalib(await api('POST', `/api/calib/${cam.index}/rods/${rod.rod}/delete`)); } catch (e) { calMsg(e.message); }
};
$('clear-pts').onclick = async () => {
  const cam = curCam(), rod = curRod(); if (!cam || !rod) return;
  try { setCalib(await api('POST', `/api/calib/${cam.index}/rods/${rod.rod}/points/clear`)); } catch (e) { calMsg(e.message); }
};
$('set-ref').onclick = async () => {
  const cam = curCam(), rod = curRod(); if (!cam || !rod) return;
  const body = { position_mm: Number($('ref-pos').value), angle_rad: Number($('ref-ang').value), travel_mm: [Number($('trav0').value), Number($('trav1').value)] };
  try { setCalib(await api('POST', `/api/calib/${cam.index}/rods/${rod.rod}/reference`, body)); calMsg(`rod ${rod.rod}: reference pose set on this frame`); } catch (e) { calMsg(e.message); }
};
$('run-cal').onclick = async () => {
  calMsg('calibrating...');
  try { setCalib(await api('POST', '/api/calibrate')); calMsg('calibrated: see the residuals'); } catch (e) { calMsg(e.message); }
};
$('save').onclick = async () => {
  try { const r = await api('POST', '/api/save'); calMsg(`saved ${r.saved.calibration}`); } catch (e) { calMsg(e.message); }
};

// The known-pose step of the selected rod: what to do, and the poses captured.
function showPoses(rod) {
  if (!rod) { $('pose-hint').textContent = 'add a rod first'; $('poses').textContent = ''; return; }
  const [lo, hi] = rod.travel_mm;
  $('pose-hint').textContent = `push rod ${rod.rod} to its left stop (${lo} mm), click "Capture left stop"; the right stop (${hi} mm) is optional`;
  $('poses').textContent = (rod.known_poses || []).map((k) => `frame ${k.frame}: ${k.position_mm} mm`).join(', ') || 'none captured';
}

async function capturePose(stop) {
  const cam = curCam(), rod = curRod();
  if (!cam || !rod) { calMsg('select a rod first'); return; }
  try {
    await api('POST', `/api/calib/${cam.index}/rods/${rod.rod}/known_pose`, { stop });
    calMsg(`rod ${rod.rod}: capturing the ${stop} stop...`);
    for (let i = 0; i < 50; i++) {
      await new Promise((r) => setTimeout(r, 100));
      const st = await api('GET', '/api/calib');
      if (!st.pending_pose) {
        setCalib(st, false);
        const r = curRod(), k = r && (r.known_poses || []).find((p) => p.position_mm === rod.travel_mm[stop === 'left' ? 0 : 1]);
        calMsg(k ? `rod ${rod.rod}: ${stop} stop captured (frame ${k.frame}, ${k.position_mm} mm)` : 'no frame captured');
        return;
      }
    }
    calMsg('no frame arrived');
  } catch (e) { calMsg(e.message); }
}
$('cap-left').onclick = () => capturePose('left');
$('cap-right').onclick = () => capturePose('right');
$('clear-poses').onclick = async () => {
  const cam = curCam(), rod = curRod(); if (!cam || !rod) return;
  try { setCalib(await api('POST', `/api/calib/${cam.index}/rods/${rod.rod}/known_poses/clear`)); } catch (e) { calMsg(e.message); }
};

function showResiduals() {
  const t = $('residuals');
  if (!rt.calib) { t.innerHTML = ''; return; }
  let html = '<tr><th>cam</th><th>rod</th><th>points</th><th>path rms / max px</th><th>edge rms mm</th><th>scale ratio</th><th>ref ncc</th><th>code-phase steps</th><th>radius ratio</th><th>travel model</th><th>known poses: error mm</th><th style="text-align:left">notes</th></tr>';
  for (const c of rt.calib.cameras) {
    for (const r of c.inputs.rods) {
      const o = c.outcomes.find((x) => x.rod === r.rod);
      const s = o && o.residuals;
      const note = o ? (o.error ? `<td class="err">${esc(o.error)}</td>` : `<td class="msg">${esc((s.warnings || []).join('; '))}</td>`) : '<td class="msg">not calibrated</td>';
      html += `<tr><td>${c.index}</td><td>${r.rod}</td><td>${r.path_points_px.length}</td>` +
        (s ? `<td>${s.path_rms_px.toFixed(2)} / ${s.path_max_px.toFixed(2)}</td><td>${s.edge_rms_mm.toFixed(3)}</td><td>${s.scale_ratio.toFixed(3)}</td><td>${s.reference_ncc.toFixed(3)}</td><td>${s.reference_code_phase_steps.toFixed(2)}</td><td>${s.radius_ratio.toFixed(3)}</td><td>${esc(s.travel_model || '')}</td><td class="known-errors">${(s.known_pose_errors_mm || []).map((e) => `frame ${e[0]}: ${e[1].toFixed(3)}`).join(', ')}</td>` : '<td></td><td></td><td></td><td></td><td></td><td></td><td></td><td></td>') +
        note + '</tr>';
    }
    for (const o of c.outcomes.filter((x) => !c.inputs.rods.some((r) => r.rod === x.rod))) {
      html += `<tr><td>${c.index}</td><td></td><td></td><td></td><td></td><td></td><td></td><td></td><td></td><td></td><td></td><td class="err">${esc(o.error || '')}</td></tr>`;
    }
  }
  t.innerHTML = html;
}

function esc(s) { return String(s).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[c])); }

connect();
drawPlots();
