// The tuning page: the live picture with its views, the settings, the tracked objects, the
// captures and the video head's figures, all kept current by the event socket.

import { Api } from './api.js';
import { Preview } from './preview.js';
import { Views } from './views.js';
import { Controls } from './controls.js';

const $ = (id) => document.getElementById(id);
const api = new Api();

function say(text, bad = false) {
  const m = $('message');
  m.textContent = text;
  m.classList.toggle('bad', bad);
}

const preview = new Preview($('video'), $('preview-note'));
const views = new Views($('overlay'), api, say);
const controls = new Controls(api, say);
window.digiview = { api, preview, views, controls };
views.onObject = (o) => aimAt(o);
// The rings are placed for the frame the picture shows, drawn with it.
preview.addEventListener('frame', (e) => views.shown(e.detail.pts));

api.on('params', (params) => {
  views.update(params);
  controls.update(params);
  showObjects(params);
  showCapture(params.CAPTURE);
});

api.on('status', showStatus);
api.on('connection', (up) => {
  if (!up) {
    $('status').textContent = 'disconnected: reconnecting…';
    $('status').classList.add('bad');
  }
});

const STATUS = ['idle', 'running', 'finished', 'error'];
const FAILURE = ['', 'source', 'encoder', 'GPU', 'attitude', 'internal', 'capture'];
const LINK = ['off', 'opening', 'open, no attitude', 'attitude coming', 'attitude stale'];

function showStatus(s) {
  const v = s.video;
  const state = STATUS[s.status] || s.status;
  const failure = s.failure ? ` (${FAILURE[s.failure] || s.failure})` : '';
  const fps = v ? ` · ${v.fps_out.toFixed(1)} fps` : ' · no video';
  $('status').textContent = `${state}${failure}${fps}`;
  $('status').classList.toggle('bad', s.status === 3);
  const rows = [];
  if (s.capture) rows.push(['capture', s.capture.why, true]);
  if (v) {
    rows.push(['frames in', `${v.fps_in.toFixed(1)} fps`], ['frames out', `${v.fps_out.toFixed(1)} fps`],
      ['dropped', `${v.dropped_renderer} renderer, ${v.dropped_encoder} encoder`],
      ['render', `${v.render_ms.toFixed(1)} ms`], ['encode', `${v.encode_ms.toFixed(1)} ms`],
      ['RTSP clients', v.rtsp_clients], ['page viewers', v.page_viewers]);
    if (v.gpu) rows.push(['GPU', `${v.gpu.adapter}, ${v.gpu.backend}: ${v.gpu.why}`]);
    const [scans, scanMs, detectMs] = v.scans;
    rows.push(['detection', scans > 0
      ? `${scans.toFixed(1)} scans/s (${scanMs.toFixed(1)} ms render, ${detectMs.toFixed(1)} ms detect)`
      : 'no scans'], ['tracked', v.tracked]);
    if (v.views_alone[0] > 0) {
      rows.push(['views alone', `${v.views_alone[0].toFixed(1)} fps, ${v.views_alone[1].toFixed(1)} ms each`]);
    }
    if (v.exposure) rows.push(['exposure', v.exposure]);
    if (v.lenses) rows.push(['lens pair', v.lenses]);
    if (v.source_down) rows.push(['source down', v.source_down]);
    if (v.thermal) rows.push(...thermalRows(v.thermal));
  }
  controls.thermal(!!(v && v.thermal));
  rows.push(...linkRows(s.autopilot));
  rows.push(['version', s.version]);
  $('figures').replaceChildren(...rows.flatMap(([k, val, bad]) => {
    const dt = document.createElement('dt');
    dt.textContent = k;
    const dd = document.createElement('dd');
    dd.textContent = val;
    dd.classList.toggle('bad', !!bad);
    return [dt, dd];
  }));
}

// The thermal sensor: what it is, and why it is down while it is.
function thermalRows(t) {
  const size = t.size ? `, ${t.size[0]}x${t.size[1]}` : '';
  const rows = [['thermal', `${t.source} (${t.lens}): ${t.frames} frames${size}`]];
  if (t.error) rows.push(['thermal down', t.error, true]);
  return rows;
}

// The MAVLink link: its state, who drives the views, and other senders of attitude (a warning).
function linkRows(a) {
  if (!a) return [['MAVLink', 'not available (off)']];
  const who = a.simulated ? "the demo's simulated flight" : 'autopilot';
  const driver = a.system_id ? `, ${who} ${a.system_id}/${a.component_id}` : '';
  const rows = [['MAVLink', `${LINK[a.link] || a.link}${driver}`]];
  if (a.others > 0) {
    const more = a.others > 1 ? ` and ${a.others - 1} more` : '';
    rows.push(['attitude also from', `${a.other_system}/${a.other_component}${more}: ignored`, true]);
  }
  return rows;
}

const deg = (r) => ((r * 180) / Math.PI).toFixed(1);

function showObjects(params) {
  const list = (params.DETECTED_ROI || []).filter((o) => o.total_detections > 0);
  const items = list.map((o) => {
    const li = document.createElement('li');
    const where = o.distance > 0 ? `, ${o.distance.toFixed(0)} m` : '';
    li.textContent = `#${o.index} score ${o.score} · yaw ${deg(o.yaw_abs)}° pitch ${deg(o.pitch_abs)}°${where}`;
    li.title = 'aim the selected camera at it';
    li.addEventListener('click', () => aimAt(o));
    return li;
  });
  if (items.length === 0) {
    const li = document.createElement('li');
    li.className = 'unavailable';
    li.textContent = 'no tracked objects';
    items.push(li);
  }
  $('objects').replaceChildren(...items);
}

// Turns the selected camera to the object: world angles for a camera locked in yaw and pitch,
// angles relative to the vehicle otherwise (conventions.md).
function aimAt(o) {
  const cam = controls.cam;
  const lock = api.params.CAM_LOCK_FLAGS[cam].flags;
  const world = (lock & 6) === 6;
  const yaw = world ? o.yaw_abs : o.yaw_rel;
  const pitch = world ? o.pitch_abs : o.pitch_rel;
  api.set('CAM_EULER', { cam_id: cam, is_delta: 0, yaw, pitch })
    .then(() => say(`cam ${cam} aimed at object #${o.index}`))
    .catch((e) => say(`CAM_EULER: ${e.message}`, true));
}

let recording = false;

function showCapture(c) {
  if (!c) return;
  recording = (c.flags & 2) !== 0;
  $('record').textContent = recording ? 'Stop recording' : 'Start recording';
}

$('still').addEventListener('click', () => {
  api.set('CAPTURE', { flags: 1 | (recording ? 2 : 0) })
    .then(() => { say('still taken'); setTimeout(listCaptures, 1000); })
    .catch((e) => say(`CAPTURE: ${e.message}`, true));
});

$('record').addEventListener('click', () => {
  api.set('CAPTURE', { flags: recording ? 0 : 2 })
    .then(() => { say(recording ? 'recording stopped' : 'recording'); setTimeout(listCaptures, 1000); })
    .catch((e) => say(`CAPTURE: ${e.message}`, true));
});

async function listCaptures() {
  try {
    const list = await api.get('/api/captures');
    $('captures').replaceChildren(...list.map((c) => {
      const li = document.createElement('li');
      const a = document.createElement('a');
      a.href = c.url;
      a.download = c.name;
      a.textContent = c.name;
      li.append(a, ` ${(c.bytes / 1e6).toFixed(1)} MB`);
      return li;
    }));
  } catch (e) {
    say(`captures: ${e.message}`, true);
  }
}

api.get('/api/lenses').then((list) => controls.lenses(list)).catch((e) => say(e.message, true));
listCaptures();
preview.start();
