// The views over the live picture: each view's rectangle outlined with its camera number, and
// the pointer gestures that steer it: drag inside a view to turn it (CAM_OFFSET: the picture
// follows the pointer), wheel or pinch to zoom (CAM_FOV), double-click to centre a point. The
// tracked objects are ringed where the views show them (the server projects them); a click on
// one hands it to `onObject`.

const LAYOUT_DEBUG = 6; // the whole fisheye frame: no camera to steer
const MIN_FOV = 0.02;
const MAX_FOV = Math.PI;
const LABEL_PX = 13; // the labels' text height on screen, CSS pixels
const MAX_AHEAD_S = 1.0; // the furthest a ring is moved on from the frame it was placed on (the tracker's 1 s in sight)
const FRAMED_MS = 500; // the picture's frames time the rings while one came this recently

export class Views {
  constructor(overlay, api, onMessage) {
    this.overlay = overlay;
    this.context = overlay.getContext('2d');
    this.api = api;
    this.say = onMessage;
    this.output = null;
    this.fovs = [];
    this.objects = [];
    this.onObject = null;
    this.pointers = new Map();
    this.busy = false;
    this.queued = null;
    overlay.addEventListener('pointerdown', (e) => this.down(e));
    overlay.addEventListener('pointermove', (e) => this.move(e));
    overlay.addEventListener('pointerup', (e) => this.up(e));
    overlay.addEventListener('pointercancel', (e) => this.up(e));
    overlay.addEventListener('wheel', (e) => this.wheel(e), { passive: false });
    overlay.addEventListener('dblclick', (e) => this.centre(e));
    // Labels are sized for the screen: drawn again when the picture's size there changes.
    new ResizeObserver(() => this.draw()).observe(overlay);
  }

  // New parameters: the output's views and each camera's fov.
  update(params) {
    this.output = params.VIDEO_OUTPUT;
    this.fovs = (params.CAM_FOV || []).map((f) => (f ? f.fov : null));
    this.objects = (params.DETECTED_ROI || []).filter((o) => o.total_detections > 0);
    this.received = performance.now();
    this.draw();
    this.animate();
  }

  // The picture now shows the frame presented at `pts` µs (null: not known): the rings are
  // drawn again, for it.
  shown(pts) {
    this.shownPts = pts;
    this.shownAt = performance.now();
    this.draw();
  }

  // Whether the picture's frames time the rings: frames are coming, with their times.
  framed() {
    return this.shownPts != null && performance.now() - this.shownAt < FRAMED_MS;
  }

  // How far (s) `object`'s rings are moved on at their velocity from the frame they were
  // placed on: to the frame the picture shows, or without a picture, for the time since the
  // update came. Within MAX_AHEAD_S either way.
  ahead(object) {
    const s = this.framed() && object.pts_us != null
      ? (this.shownPts - object.pts_us) / 1e6
      : (performance.now() - (this.received || 0)) / 1000;
    return Math.max(-MAX_AHEAD_S, Math.min(s, MAX_AHEAD_S));
  }

  // Without a picture to time them, moving rings are drawn on every frame the browser
  // paints, moved on from where the last update put it at its velocity (the tracker's
  // prediction), for at most MAX_AHEAD_S, until the next update.
  animate() {
    const moving = this.objects.some((o) => (o.views || []).some((m) => m.vx || m.vy));
    if (!moving || this.animating) return;
    this.animating = true;
    const step = () => {
      const ahead = (performance.now() - this.received) / 1000;
      const still = !this.objects.some((o) => (o.views || []).some((m) => m.vx || m.vy));
      if (still || ahead > MAX_AHEAD_S) {
        this.animating = false;
        return;
      }
      if (!this.framed()) this.draw();
      requestAnimationFrame(step);
    };
    requestAnimationFrame(step);
  }

  draw() {
    const o = this.output;
    if (!o) return;
    if (this.overlay.width !== o.width || this.overlay.height !== o.height) {
      this.overlay.width = o.width;
      this.overlay.height = o.height;
    }
    const g = this.context;
    g.clearRect(0, 0, o.width, o.height);
    // Canvas pixels per CSS pixel: the labels keep LABEL_PX on screen however the picture is
    // scaled (a phone shows a 1280-wide frame about 390 px wide).
    const scale = o.width / (this.overlay.clientWidth || o.width);
    const font = LABEL_PX * scale;
    const pad = 4 * scale;
    g.lineWidth = 2 * Math.max(1, scale);
    g.font = `${Math.round(font)}px system-ui, sans-serif`;
    g.textBaseline = 'top';
    // Every label's box, so that none is drawn over another.
    const placed = [];
    const label = (text, box, colour) => {
      g.fillStyle = 'rgba(0, 0, 0, 0.6)';
      g.fillRect(box.x, box.y, box.w, box.h);
      g.fillStyle = colour;
      g.fillText(text, box.x + pad, box.y + pad);
      placed.push(box);
    };
    const sized = (text, x, y) => ({ x, y, w: g.measureText(text).width + 2 * pad, h: font + 2 * pad });
    const free = (b) => b.x >= 0 && b.y >= 0 && b.x + b.w <= o.width && b.y + b.h <= o.height
      && !placed.some((p) => b.x < p.x + p.w && p.x < b.x + b.w && b.y < p.y + p.h && p.y < b.y + b.h);
    this.views().forEach((v, cam) => {
      g.strokeStyle = 'rgba(79, 179, 255, 0.9)';
      g.strokeRect(v.x + 1, v.y + 1, v.w - 2, v.h - 2);
      const text = o.layout_mode === LAYOUT_DEBUG ? 'fisheye' : `cam ${cam}`;
      label(text, sized(text, v.x + pad, v.y + pad), '#fff');
    });
    g.strokeStyle = 'rgba(255, 170, 40, 0.95)';
    const rings = [];
    for (const object of this.objects) {
      const ahead = this.ahead(object);
      for (const seen of object.views || []) {
        const m = { ...seen, x: seen.x + (seen.vx || 0) * ahead, y: seen.y + (seen.vy || 0) * ahead };
        // Moving: it has a velocity and is within reach of its frame (past 1 s it stands).
        rings.push({ index: object.index, x: m.x, y: m.y, moving: Boolean(m.vx || m.vy) && Math.abs(ahead) < MAX_AHEAD_S });
        g.beginPath();
        g.arc(m.x, m.y, m.radius, 0, 2 * Math.PI);
        g.stroke();
        // Beside the ring, on whichever side is clear of the labels drawn; none if no side is.
        const text = `#${object.index}`;
        const { w, h } = sized(text, 0, 0);
        const r = m.radius + pad;
        const box = [[m.x + r, m.y - r - h], [m.x + r, m.y + r], [m.x - r - w, m.y - r - h], [m.x - r - w, m.y + r]]
          .map(([x, y]) => sized(text, x, y)).find(free);
        if (box) label(text, box, 'rgba(255, 170, 40, 0.95)');
      }
    }
    // Where the labels lie and their text's height, and where the rings are, in the canvas's
    // pixels (for tests and tools).
    this.overlay.dataset.labels = JSON.stringify(placed.map((b) => ({ ...b, font })));
    this.overlay.dataset.rings = JSON.stringify(rings);
    this.overlay.dataset.pts = this.framed() ? String(this.shownPts) : '';
  }

  // The tracked object ringed at output point (x, y), if any (a little slack around the ring).
  objectAt(x, y) {
    const slack = 6 * Math.max(1, this.overlay.width / 960);
    return this.objects.find((o) => (o.views || []).some((m) => Math.hypot(m.x - x, m.y - y) <= m.radius + slack));
  }

  views() {
    return this.output ? this.output.views : [];
  }

  // The view under a pointer event, with the point in output pixels.
  hit(event) {
    const r = this.overlay.getBoundingClientRect();
    const x = ((event.clientX - r.left) / r.width) * this.overlay.width;
    const y = ((event.clientY - r.top) / r.height) * this.overlay.height;
    if (!this.output || this.output.layout_mode === LAYOUT_DEBUG) return null;
    const cam = this.views().findIndex((v) => x >= v.x && x < v.x + v.w && y >= v.y && y < v.y + v.h);
    return cam < 0 ? null : { cam, x, y, view: this.views()[cam] };
  }

  // Sends one SET at a time; while one is out, the next waits, and offsets dragged meanwhile
  // add up into it (small turns add), so no movement is lost.
  send(param, fields) {
    if (this.busy) {
      const q = this.queued;
      if (q && q[0] === 'CAM_OFFSET' && param === 'CAM_OFFSET' && q[1].cam_id === fields.cam_id && !fields.centre) {
        q[1].x += fields.x;
        q[1].y += fields.y;
      } else {
        this.queued = [param, fields];
      }
      return;
    }
    this.busy = true;
    const { centre, ...sent } = fields;
    this.api
      .set(param, sent)
      .catch((e) => this.say(`${param}: ${e.message}`, true))
      .finally(() => {
        this.busy = false;
        const next = this.queued;
        this.queued = null;
        if (next) this.send(...next);
      });
  }

  down(event) {
    const hit = this.hit(event);
    if (!hit) return;
    this.overlay.setPointerCapture(event.pointerId);
    this.pointers.set(event.pointerId, { ...hit, lastX: hit.x, lastY: hit.y, moved: false });
    this.overlay.classList.add('dragging');
    if (this.pointers.size === 2) {
      this.pinchStart = this.spread();
      this.pointers.forEach((q) => { q.moved = true; }); // a pinch is no click
    }
  }

  move(event) {
    const p = this.pointers.get(event.pointerId);
    if (!p) return;
    const r = this.overlay.getBoundingClientRect();
    const x = ((event.clientX - r.left) / r.width) * this.overlay.width;
    const y = ((event.clientY - r.top) / r.height) * this.overlay.height;
    if (this.pointers.size === 2) {
      Object.assign(p, { lastX: x, lastY: y });
      const now = this.spread();
      if (this.pinchStart > 0 && now > 0) this.zoom(p.cam, this.pinchStart / now);
      this.pinchStart = now;
      return;
    }
    const dx = x - p.lastX;
    const dy = y - p.lastY;
    if (Math.abs(dx) + Math.abs(dy) < 2) return;
    Object.assign(p, { lastX: x, lastY: y, moved: true });
    // Aim at the point the pointer left: the picture follows the pointer.
    this.send('CAM_OFFSET', { cam_id: p.cam, x: -dx / p.view.w, y: -dy / p.view.h });
  }

  up(event) {
    const p = this.pointers.get(event.pointerId);
    this.pointers.delete(event.pointerId);
    if (p && !p.moved && this.pointers.size === 0 && event.type === 'pointerup') {
      const o = this.objectAt(p.x, p.y);
      if (o && this.onObject) this.onObject(o);
    }
    if (this.pointers.size === 0) this.overlay.classList.remove('dragging');
  }

  spread() {
    const [a, b] = [...this.pointers.values()];
    return a && b ? Math.hypot(a.lastX - b.lastX, a.lastY - b.lastY) : 0;
  }

  zoom(cam, factor) {
    const fov = this.fovs[cam];
    if (!fov) return;
    const next = Math.min(MAX_FOV, Math.max(MIN_FOV, fov * factor));
    this.fovs[cam] = next;
    this.send('CAM_FOV', { cam_id: cam, fov: next });
  }

  wheel(event) {
    const hit = this.hit(event);
    if (!hit) return;
    event.preventDefault();
    this.zoom(hit.cam, Math.exp(event.deltaY * 0.001));
  }

  centre(event) {
    const hit = this.hit(event);
    if (!hit) return;
    const v = hit.view;
    const x = (hit.x - v.x) / v.w - 0.5;
    const y = (hit.y - v.y) / v.h - 0.5;
    this.send('CAM_OFFSET', { cam_id: hit.cam, x, y, centre: true });
  }
}
