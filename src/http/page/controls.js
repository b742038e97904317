// The settings beside the picture: one small form per parameter type, filled from the pushed
// state and sending a SET of the one field changed. Angles are shown and typed in degrees.

const LAYOUTS = ['0 one square', '1 two squares stacked', '2 two panoramas stacked',
  '3 two squares over a panorama', '4 four squares', '5 three squares over a panorama',
  '6 fisheye (debug)'];
const OVERLAYS = ['0 none', '1 one tile, top right', '2 column, right', '3 column, left',
  '4 row, top', '5 row, bottom'];
const SORTING = ['0 by score', '1 by age', '2 by score, tiles kept'];
const PALETTES = ['0 white hot', '1 black hot', '2 ironbow', '3 rainbow', '4 arctic', '5 lava'];
const GAINS = ['0 automatic', '1 fixed span'];
const SHOWS = ['0 off', '1 blended', '2 picture in picture', '3 thermal alone'];
const deg = (r) => (r * 180) / Math.PI;

// [field, label, kind, options]; kind: int, num, deg, bool, choice, ratio.
const FORMS = {
  output: ['VIDEO_OUTPUT', [
    ['width', 'width', 'int'], ['height', 'height', 'int'], ['fps', 'fps', 'int'],
    ['layout_mode', 'layout', 'choice', LAYOUTS],
    ['detection_overlay_mode', 'overlay', 'choice', OVERLAYS],
  ]],
  lens: ['LENS', [['lens_id', 'lens', 'choice', []]]],
  sensor: ['CAM_SENSOR', [
    ['ae', 'auto exposure', 'bool'], ['target_brightness', 'target brightness', 'int'],
    ['exposure_value', 'exposure µs', 'int'], ['gain_value', 'gain (1000 = 1×)', 'int'],
  ]],
  general: ['GENERAL_SETTINGS', [
    ['camera_width', 'camera width', 'int'], ['camera_height', 'camera height', 'int'],
    ['roi_width', 'crop width', 'int'], ['roi_height', 'crop height', 'int'],
    ['camera_fps', 'camera fps', 'int'], ['mount_yaw', 'mount yaw °', 'deg'],
    ['mount_pitch', 'mount pitch °', 'deg'], ['mount_roll', 'mount roll °', 'deg'],
    ['run_ai', 'detection on', 'bool'],
  ]],
  detection: ['DETECTION', [
    ['mode', 'mode', 'int'], ['sorting_mode', 'sorting', 'choice', SORTING],
    ['crop_confidence_threshold', 'crop threshold', 'ratio'],
    ['var_confidence_threshold', 'scan threshold', 'ratio'],
    ['crop_box_limit', 'crop box limit', 'int'], ['var_box_limit', 'scan box limit', 'int'],
    ['crop_box_overlap', 'crop overlap', 'ratio'], ['var_box_overlap', 'scan overlap', 'ratio'],
    ['creation_score_scale', 'creation score', 'int'],
    ['bonus_detection_scale', 'bonus, scan', 'int'], ['bonus_redetection_scale', 'bonus, track', 'int'],
    ['missed_detection_penalty', 'penalty, scan', 'int'],
    ['missed_redetection_penalty', 'penalty, track', 'int'],
  ]],
  thermal: ['THERMAL', [
    ['palette', 'palette', 'choice', PALETTES], ['gain', 'gain', 'choice', GAINS],
    ['span_low', 'span from K', 'num'], ['span_high', 'span to K', 'num'],
    ['blend', 'blend share', 'ratio'], ['zoom', 'zoom (1 to 8×)', 'int'],
  ]],
};

// The camera form: [param, field, label, kind, options].
const CAMERA = [
  ['CAM_EULER', 'yaw', 'yaw °', 'deg'], ['CAM_EULER', 'pitch', 'pitch °', 'deg'],
  ['CAM_EULER', 'roll', 'roll °', 'deg'], ['CAM_FOV', 'fov', 'fov °', 'deg'],
  ['CAM_CROP_MODE', 'mode', 'crop mode', 'int'],
  ['CAM_LOCK_FLAGS', 'flags', 'lock (roll 1, pitch 2, yaw 4)', 'int'],
  ['CAM_CONTROL_MODE', 'mode', 'control mode', 'int'],
  ['CAM_TARGET', 't_latitude', 'target latitude °', 'num'],
  ['CAM_TARGET', 't_longitude', 'target longitude °', 'num'],
  ['CAM_TARGET', 't_altitude', 'target altitude m', 'num'],
  ['CAM_THERMAL', 'show', 'thermal', 'choice', SHOWS],
];

function input(kind, options) {
  if (kind === 'choice') {
    const select = document.createElement('select');
    options.forEach((text, value) => select.add(new Option(text, value)));
    return select;
  }
  const el = document.createElement('input');
  if (kind === 'bool') el.type = 'checkbox';
  else {
    el.type = 'number';
    el.step = kind === 'int' ? '1' : 'any';
  }
  return el;
}

// Shows `value` in a field, unless it is being typed in (`force`: after its own change, when
// the server's value replaces what was typed).
function show(el, kind, value, force = false) {
  if ((!force && document.activeElement === el) || value === undefined || value === null) return;
  if (kind === 'bool') el.checked = value !== 0;
  else if (kind === 'deg') el.value = deg(value).toFixed(2);
  else if (kind === 'ratio') el.value = Number(value).toFixed(3);
  else el.value = value;
}

function read(el, kind) {
  if (kind === 'bool') return el.checked ? 1 : 0;
  if (kind === 'deg') return `${el.value}deg`;
  return Number(el.value);
}

function row(form, name, label) {
  const id = `${form.id}-${name}`;
  const l = document.createElement('label');
  l.htmlFor = id;
  l.textContent = label;
  return [l, id];
}

export class Controls {
  constructor(api, say) {
    this.api = api;
    this.say = say;
    this.cam = 0;
    this.fields = [];
    for (const [formId, [param, fields]] of Object.entries(FORMS)) {
      const form = document.getElementById(formId);
      for (const [name, label, kind, options] of fields) {
        const [l, id] = row(form, name, label);
        const el = input(kind, options || []);
        el.id = id;
        el.name = name;
        form.append(l, el);
        el.addEventListener('change', () => {
          if (el.value === '' && kind !== 'bool') {
            this.say(`${label}: give a value`, true);
            this.showBack(param, null);
            return;
          }
          this.set(param, { [name]: read(el, kind) });
        });
        this.fields.push({ param, name, kind, el, perCamera: false });
      }
    }
    const pick = document.getElementById('cam-pick');
    for (let i = 0; i < 4; i++) pick.add(new Option(`cam ${i}`, i));
    pick.addEventListener('change', () => {
      this.cam = Number(pick.value);
      // Typed-in target coordinates belong to the camera they were typed for.
      this.fields.filter((f) => f.param === 'CAM_TARGET').forEach((f) => { f.el.value = ''; });
      if (this.params) this.update(this.params);
    });
    const camera = document.getElementById('camera');
    for (const [param, name, label, kind, options] of CAMERA) {
      const [l, id] = row(camera, `${param}-${name}`, label);
      const el = input(kind, options || []);
      el.id = id;
      camera.append(l, el);
      el.addEventListener('change', () => {
        if (param === 'CAM_TARGET') {
          this.setTarget();
          return;
        }
        const fields = { cam_id: this.cam, [name]: read(el, kind) };
        if (param === 'CAM_EULER') fields.is_delta = 0;
        this.set(param, fields);
      });
      this.fields.push({ param, name, kind, el, perCamera: true, label: l });
    }
    this.lensSelect = document.getElementById('lens-lens_id');
    this.thermal(false);
  }

  // The thermal settings show only where the head has a thermal sensor.
  thermal(on) {
    document.getElementById('thermal-panel').hidden = !on;
    for (const f of this.fields.filter((g) => g.param === 'CAM_THERMAL')) {
      f.el.hidden = !on;
      f.label.hidden = !on;
    }
  }

  // A target is a point: all three coordinates go together (x = y = 0 means "these
  // coordinates" to CAM_TARGET), and the camera then follows it (coordinate control).
  setTarget() {
    const fields = { cam_id: this.cam, x: 0, y: 0 };
    for (const f of this.fields.filter((g) => g.param === 'CAM_TARGET')) {
      if (f.el.value === '') {
        this.say('CAM_TARGET: give the latitude, longitude and altitude', true);
        return;
      }
      fields[f.name] = Number(f.el.value);
    }
    this.set('CAM_TARGET', fields);
  }

  // SETs the fields, then shows what the server holds in them (not what was typed) and says
  // so where it differs: a value the protocol clamped or ignored (the reply's `clamped`).
  set(param, fields) {
    this.api
      .set(param, fields)
      .then((now) => {
        this.showBack(param, now);
        const clamped = Object.entries((now && now.clamped) || {});
        if (clamped.length === 0) {
          this.say(`${param} set`);
          return;
        }
        const field = (name) => this.fields.find((f) => f.param === param && f.name === name);
        const shown = (name, v) => (field(name) && field(name).kind === 'deg' ? `${deg(v).toFixed(2)}°` : v);
        const told = clamped.map(([name, c]) => `${name} ${shown(name, c.asked)} is not taken: it is ${shown(name, c.set)}`);
        this.say(`${param}: ${told.join('; ')}`, true);
      })
      .catch((e) => {
        this.say(`${param}: ${e.message}`, true);
        this.showBack(param, null);
      });
  }

  // The server's values in `param`'s fields: `now` (a SET's reply, for this camera), else
  // the state the page has.
  showBack(param, now) {
    for (const f of this.fields.filter((g) => g.param === param)) {
      let value = now;
      if (!value && this.params) {
        value = this.params[param];
        if (f.perCamera) value = value && value[this.cam];
      }
      show(f.el, f.kind, value ? value[f.name] : undefined, true);
    }
  }

  lenses(list) {
    this.lensSelect.replaceChildren(...list.map((l) => new Option(`${l.lens_id} ${l.name}`, l.lens_id)));
    if (this.params) this.update(this.params);
  }

  update(params) {
    this.params = params;
    for (const f of this.fields) {
      let value = params[f.param];
      if (f.perCamera) value = value && value[this.cam];
      show(f.el, f.kind, value ? value[f.name] : undefined);
    }
  }
}
