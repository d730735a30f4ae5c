// dronetrack operator page: plan view (SVG, metres, x east / y north), altitude strip,
// selected-track panel, node health and alerts, fed by /api/* and the /api/stream SSE.
// Plain browser JavaScript: no build step, nothing loaded from outside this server.
'use strict';

(() => {
  const SVG_NS = 'http://www.w3.org/2000/svg';
  const TRAIL_S = 60;           // trail and altitude-strip window, stream seconds
  const DOA_FRESH_S = 1.5;      // a DOA older than this (stream time) is not drawn
  const ELLIPSE_SIGMA = 2.4477; // 95 % of a 2-D Gaussian: sqrt(chi2_2(0.95))
  const BANNER_S = 15;          // an alert stays in the banner this long (stream time)

  const state = {
    site: null,
    time: 0,
    tracks: new Map(),   // id -> latest track JSON
    trails: new Map(),   // id -> [[t, x, y, z], ...]
    doas: new Map(),     // "array/source" -> DOA JSON
    nodes: [],
    alerts: [],
    classFilter: 'all',  // which tracks the plan and the list show (drone / ground / ...)
    selected: null,      // track id
    bannerAlert: null,
    view: { cx: 0, cy: 0, scale: 2 },  // centre (m) and pixels per metre
    fitted: false,
    userView: false,     // the operator panned or zoomed: keep the view on resize
  };

  const $ = (id) => document.getElementById(id);
  const plan = $('plan');
  const altitude = $('altitude');

  // ---------- helpers ----------
  function el(tag, attrs, parent) {
    const node = document.createElementNS(SVG_NS, tag);
    for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, v);
    if (parent) parent.appendChild(node);
    return node;
  }
  const fmt = (v, digits = 1) => (Number.isFinite(v) ? v.toFixed(digits) : '–');
  function niceStep(raw) {
    const p = Math.pow(10, Math.floor(Math.log10(raw)));
    for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
    return 10 * p;
  }
  function toScreen(x, y) {
    const r = plan.getBoundingClientRect();
    const v = state.view;
    return [r.width / 2 + (x - v.cx) * v.scale, r.height / 2 - (y - v.cy) * v.scale];
  }
  function toWorld(sx, sy) {
    const r = plan.getBoundingClientRect();
    const v = state.view;
    return [v.cx + (sx - r.width / 2) / v.scale, v.cy - (sy - r.height / 2) / v.scale];
  }
  const arrayIds = () => (state.site ? state.site.arrays.map((a) => a.id) : []);

  // ---------- view: fit, pan, zoom ----------
  function fitView() {
    if (!state.site) return;
    const xs = [], ys = [];
    for (const a of state.site.arrays) { xs.push(a.position_m[0]); ys.push(a.position_m[1]); }
    for (const z of state.site.zones) for (const p of z.polygon_m) { xs.push(p[0]); ys.push(p[1]); }
    for (const t of state.tracks.values()) { xs.push(t.position_m[0]); ys.push(t.position_m[1]); }
    if (xs.length === 0) { xs.push(0); ys.push(0); }
    const minX = Math.min(...xs), maxX = Math.max(...xs), minY = Math.min(...ys), maxY = Math.max(...ys);
    const r = plan.getBoundingClientRect();
    const w = Math.max(maxX - minX, 20), h = Math.max(maxY - minY, 20);
    state.view.cx = (minX + maxX) / 2;
    state.view.cy = (minY + maxY) / 2;
    state.view.scale = Math.max(0.05, Math.min((r.width - 80) / (w * 1.3), (r.height - 80) / (h * 1.3)));
    state.userView = false;
    render();
  }
  function zoomAt(factor, sx, sy) {
    const [wx, wy] = toWorld(sx, sy);
    state.view.scale = Math.min(200, Math.max(0.02, state.view.scale * factor));
    const [nx, ny] = toWorld(sx, sy);
    state.view.cx += wx - nx;
    state.view.cy += wy - ny;
    state.userView = true;
    render();
  }
  $('zoom-in').addEventListener('click', () => { const r = plan.getBoundingClientRect(); zoomAt(1.4, r.width / 2, r.height / 2); });
  $('zoom-out').addEventListener('click', () => { const r = plan.getBoundingClientRect(); zoomAt(1 / 1.4, r.width / 2, r.height / 2); });
  $('zoom-fit').addEventListener('click', fitView);
  plan.addEventListener('wheel', (e) => {
    e.preventDefault();
    const r = plan.getBoundingClientRect();
    zoomAt(Math.exp(-e.deltaY * 0.0015), e.clientX - r.left, e.clientY - r.top);
  }, { passive: false });

  let drag = null;
  plan.addEventListener('pointerdown', (e) => {
    drag = { x: e.clientX, y: e.clientY, cx: state.view.cx, cy: state.view.cy, moved: false, target: e.target };
    plan.setPointerCapture(e.pointerId);
  });
  plan.addEventListener('pointermove', (e) => {
    const r = plan.getBoundingClientRect();
    const [wx, wy] = toWorld(e.clientX - r.left, e.clientY - r.top);
    $('plan-cursor').textContent = `x ${fmt(wx)} m, y ${fmt(wy)} m`;
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    if (Math.hypot(dx, dy) > 4) { drag.moved = true; plan.classList.add('dragging'); }
    if (drag.moved) {
      state.view.cx = drag.cx - dx / state.view.scale;
      state.view.cy = drag.cy + dy / state.view.scale;
      state.userView = true;
      render();
    }
  });
  plan.addEventListener('pointerup', (e) => {
    plan.classList.remove('dragging');
    if (drag && !drag.moved) {
      const hit = drag.target.closest ? drag.target.closest('[data-track-id]') : null;
      if (hit) select(Number(hit.dataset.trackId));
    }
    drag = null;
    plan.releasePointerCapture(e.pointerId);
  });
  window.addEventListener('resize', () => (state.userView ? render() : fitView()));

  function select(id) {
    state.selected = id;
    render();
  }

  // ---------- drawing: plan ----------
  function drawGrid(g, r) {
    const [x0, y1] = toWorld(0, 0);
    const [x1, y0] = toWorld(r.width, r.height);
    const step = niceStep(60 / state.view.scale);
    const grid = el('g', { class: 'grid' }, g);
    for (let x = Math.ceil(x0 / step) * step; x <= x1; x += step) {
      const [sx] = toScreen(x, 0);
      const major = Math.abs(x / (step * 5) - Math.round(x / (step * 5))) < 1e-6;
      el('line', { x1: sx, y1: 0, x2: sx, y2: r.height, class: major ? 'major' : '' }, grid);
      el('text', { x: sx + 3, y: r.height - 22 }, grid).textContent = `${+x.toFixed(3)}`;
    }
    for (let y = Math.ceil(y0 / step) * step; y <= y1; y += step) {
      const [, sy] = toScreen(0, y);
      const major = Math.abs(y / (step * 5) - Math.round(y / (step * 5))) < 1e-6;
      el('line', { x1: 0, y1: sy, x2: r.width, y2: sy, class: major ? 'major' : '' }, grid);
      el('text', { x: r.width - 40, y: sy - 3 }, grid).textContent = `${+y.toFixed(3)}`;
    }
  }
  function drawScaleAndNorth(g, r) {
    const metres = niceStep(120 / state.view.scale);
    const px = metres * state.view.scale;
    const bar = el('g', { class: 'scale-bar', id: 'scale-bar', 'data-metres': metres }, g);
    const x = 16, y = r.height - 36;
    el('line', { x1: x, y1: y, x2: x + px, y2: y }, bar);
    el('line', { x1: x, y1: y - 5, x2: x, y2: y + 5 }, bar);
    el('line', { x1: x + px, y1: y - 5, x2: x + px, y2: y + 5 }, bar);
    el('text', { x: x + px / 2, y: y - 8, 'text-anchor': 'middle' }, bar).textContent = `${metres} m`;
    const north = el('g', { class: 'north', id: 'north-arrow', transform: `translate(${r.width - 30},40)` }, g);
    el('path', { d: 'M0,-22 L8,6 L0,0 L-8,6 Z' }, north);
    el('text', { x: 0, y: 20, 'text-anchor': 'middle' }, north).textContent = 'N';
  }
  function ellipsePath(t) {
    const c = t.covariance_xy_m2;
    const a = c[0][0], b = c[0][1], d = c[1][1];
    if (![a, b, d].every(Number.isFinite)) return null;
    const tr = (a + d) / 2, det = Math.sqrt(Math.max(0, ((a - d) / 2) ** 2 + b * b));
    const l1 = Math.max(tr + det, 0), l2 = Math.max(tr - det, 0);
    const angle = Math.atan2(l1 - a, b || 1e-12);  // eigenvector of l1: (b, l1 - a)
    const theta = (b === 0 && a >= d) ? 0 : (b === 0 ? Math.PI / 2 : angle);
    return { rx: ELLIPSE_SIGMA * Math.sqrt(l1), ry: ELLIPSE_SIGMA * Math.sqrt(l2), theta };
  }
  function nodeState(arrayId) {
    const n = state.nodes.find((x) => x.array === arrayId);
    return n ? n.state : 'unknown';
  }
  // Unit horizontal directions to draw for a DOA: its own, or a cone's two horizontal lines.
  function horizontalRays(d) {
    if (d.cone) {
      const [ax, ay] = d.cone.axis;
      const h = Math.hypot(ax, ay);
      const c = Math.cos(d.cone.angle_deg * Math.PI / 180) / Math.max(h, 1e-9);
      if (h < 1e-3 || Math.abs(c) > 1) return [];
      const psi = Math.atan2(ay, ax);
      const spread = Math.acos(c);
      return [psi + spread, psi - spread].map((phi) => [Math.cos(phi), Math.sin(phi)]);
    }
    const h = Math.hypot(d.direction[0], d.direction[1]);
    return h < 1e-3 ? [] : [[d.direction[0] / h, d.direction[1] / h]];
  }
  function drawPlan() {
    const r = plan.getBoundingClientRect();
    plan.replaceChildren();
    if (!state.site) return;
    const g = el('g', {}, plan);
    drawGrid(g, r);

    const active = new Set();
    for (const a of state.alerts) {
      if (a.entered && state.tracks.has(a.track_id)) active.add(a.zone);
      if (!a.entered) active.delete(a.zone);
    }
    for (const z of state.site.zones) {
      const zg = el('g', { class: 'zone' + (active.has(z.name) ? ' active' : ''), 'data-zone': z.name }, g);
      el('polygon', { points: z.polygon_m.map((p) => toScreen(p[0], p[1]).join(',')).join(' ') }, zg);
      const cx = z.polygon_m.reduce((s, p) => s + p[0], 0) / z.polygon_m.length;
      const top = Math.max(...z.polygon_m.map((p) => p[1]));
      const [sx, sy] = toScreen(cx, top);
      el('text', { x: sx, y: sy - 4, 'text-anchor': 'middle' }, zg).textContent = z.name;
    }

    // A moving array's path so far (its node's pose stamps), under everything else.
    const paths = el('g', { class: 'array-paths' }, g);
    for (const n of state.nodes) {
      if (!n.path || n.path.length < 2) continue;
      el('polyline', { class: 'array-path', 'data-array-path': n.array,
                       points: n.path.map((p) => toScreen(p[1], p[2]).join(',')).join(' ') }, paths);
    }

    // DOA rays: the direction's horizontal part from where the array was, fading with age. A
    // cone (two mics) is drawn as what it is: the two horizontal directions at its angle from
    // the mic axis, mirror images of each other.
    const reach = Math.hypot(r.width, r.height) / state.view.scale;
    const rays = el('g', { class: 'rays' }, g);
    for (const d of state.doas.values()) {
      const age = state.time - d.t;
      if (age > DOA_FRESH_S) continue;
      const a = state.site.arrays.find((x) => x.id === d.array);
      if (!a) continue;
      const origin = d.pose ? d.pose.centre_m : a.centre_m;
      const opacity = Math.max(0.15, (0.3 + 0.7 * (d.quality || 0)) * (1 - age / DOA_FRESH_S));
      const [x0, y0] = toScreen(origin[0], origin[1]);
      for (const u of horizontalRays(d)) {
        const [x1, y1] = toScreen(origin[0] + u[0] * reach, origin[1] + u[1] * reach);
        el('line', { x1: x0, y1: y0, x2: x1, y2: y1, class: 'ray' + (d.cone ? ' cone' : ''),
                     'data-doa-array': d.array, 'stroke-opacity': opacity.toFixed(2) }, rays);
      }
    }

    for (const a of state.site.arrays) {
      const stale = nodeState(a.id) === 'stale';
      const node = state.nodes.find((x) => x.array === a.id);
      const pose = node && node.pose;  // a moving array: where it is now
      const ag = el('g', { class: 'array' + (stale ? ' stale' : '') + (pose ? ' moving' : ''),
                           'data-array-id': a.id, 'data-node-state': nodeState(a.id) }, g);
      const where = pose ? pose.centre_m : a.position_m;
      const yaw = pose ? pose.attitude_deg[0] : a.yaw_deg;
      const [sx, sy] = toScreen(where[0], where[1]);
      el('rect', { class: 'body', x: sx - 6, y: sy - 6, width: 12, height: 12,
                   transform: `rotate(${-yaw} ${sx} ${sy})` }, ag);
      el('text', { x: sx + 10, y: sy + 16 }, ag).textContent = a.id + (stale ? ' (stale)' : '');
    }

    const trails = el('g', { class: 'trails' }, g);
    for (const [id, points] of state.trails) {
      if (points.length < 2) continue;
      el('polyline', { class: 'trail' + (id === state.selected ? ' selected' : ''), 'data-trail-id': id,
                       points: points.map((p) => toScreen(p[1], p[2]).join(',')).join(' ') }, trails);
    }
    for (const t of state.tracks.values()) {
      if (!shown(t)) continue;
      // A track resting on one array (range from its motion or its hypotheses, not from a
      // second bearing) is drawn dashed and says so.
      const oneArray = t.one_array || t.contributing_arrays.length === 1;
      const tg = el('g', { class: `track ${t.status} class-${t.class}` + (oneArray ? ' one-array' : '') +
                             (t.id === state.selected ? ' selected' : ''),
                           'data-track-id': t.id, 'data-arrays': t.contributing_arrays.length }, g);
      const [sx, sy] = toScreen(t.position_m[0], t.position_m[1]);
      const e = ellipsePath(t);
      if (e) {
        el('ellipse', { class: 'ellipse', cx: sx, cy: sy, rx: Math.max(1, e.rx * state.view.scale),
                        ry: Math.max(1, e.ry * state.view.scale),
                        transform: `rotate(${-e.theta * 180 / Math.PI} ${sx} ${sy})` }, tg);
      }
      // Where it will be in 5 s.
      const [vx, vy] = toScreen(t.position_m[0] + 5 * t.velocity_mps[0], t.position_m[1] + 5 * t.velocity_mps[1]);
      el('line', { class: 'velocity', x1: sx, y1: sy, x2: vx, y2: vy }, tg);
      el('circle', { class: 'dot', cx: sx, cy: sy, r: 7 }, tg);
      el('text', { x: sx + 10, y: sy - 8 }, tg).textContent =
        `T${t.id} ${fmt(t.position_m[2], 0)} m` + (oneArray ? ` (${t.contributing_arrays[0]} only)` : '');
    }
    drawScaleAndNorth(g, r);
  }

  // ---------- drawing: altitude strip ----------
  function drawAltitude() {
    const r = altitude.getBoundingClientRect();
    altitude.replaceChildren();
    const left = 40, right = 8, top = 8, bottom = 18;
    const t1 = state.time, t0 = t1 - TRAIL_S;
    let maxZ = 10;
    for (const pts of state.trails.values()) for (const p of pts) if (p[0] >= t0) maxZ = Math.max(maxZ, p[3]);
    maxZ = niceStep(maxZ / 4) * 4;
    const sx = (t) => left + (t - t0) / (t1 - t0) * (r.width - left - right);
    const sy = (z) => r.height - bottom - Math.max(0, z) / maxZ * (r.height - top - bottom);
    const axis = el('g', { class: 'axis' }, altitude);
    for (let z = 0; z <= maxZ + 1e-9; z += maxZ / 4) {
      el('line', { x1: left, x2: r.width - right, y1: sy(z), y2: sy(z) }, axis);
      el('text', { x: 4, y: sy(z) + 3 }, axis).textContent = `${+z.toFixed(1)} m`;
    }
    for (let t = Math.ceil(t0 / 10) * 10; t <= t1; t += 10) {
      el('text', { x: sx(t), y: r.height - 4, 'text-anchor': 'middle' }, axis).textContent = `${t} s`;
    }
    for (const [id, pts] of state.trails) {
      const visible = pts.filter((p) => p[0] >= t0);
      if (visible.length < 2) continue;
      el('polyline', { class: 'alt-line' + (id === state.selected ? ' selected' : ''), 'data-alt-track-id': id,
                       points: visible.map((p) => `${sx(p[0]).toFixed(1)},${sy(p[3]).toFixed(1)}`).join(' ') }, altitude);
    }
  }

  // ---------- panels ----------
  function renderSelected() {
    const panel = $('selected-track');
    const t = state.selected !== null ? state.tracks.get(state.selected) : null;
    $('selected-fields').hidden = !t;
    $('selected-hint').hidden = !!t;
    $('selected-hint').textContent = state.selected !== null && !t
      ? `Track ${state.selected} is no longer live.` : 'Click a track on the plan or in the list.';
    panel.dataset.trackId = t ? t.id : '';
    $('selected-id').textContent = t ? `T${t.id}` : '';
    if (!t) return;
    const set = (field, text, value) => {
      const dd = panel.querySelector(`[data-field="${field}"]`);
      dd.textContent = text;
      if (value !== undefined) dd.dataset.value = value;
    };
    const [x, y, z] = t.position_m;
    const sd = t.position_std_m;
    set('position', `${fmt(x)} m E, ${fmt(y)} m N`, `${x},${y}`);
    set('altitude', `${fmt(z)} m`, z);
    set('speed', `${fmt(t.speed_mps)} m/s (ground ${fmt(t.ground_speed_mps)} m/s)`, t.speed_mps);
    set('heading', `${fmt(t.heading_deg, 0)}°`, t.heading_deg);
    set('climb', `${fmt(t.velocity_mps[2])} m/s`, t.velocity_mps[2]);
    set('uncertainty', `x ${fmt(sd[0])} m, y ${fmt(sd[1])} m, z ${fmt(sd[2])} m`, Math.max(...sd));
    set('status', t.status);
    set('class', `${t.class} (${fmt(100 * t.class_confidence, 0)} %)`, t.class);
    set('arrays', t.one_array ? `${t.contributing_arrays.join(', ')} only (one-array track, ${t.hypotheses} hypotheses)`
      : t.contributing_arrays.length === 1 ? `${t.contributing_arrays[0]} only`
      : t.contributing_arrays.length ? t.contributing_arrays.join(', ') : 'none', t.contributing_arrays.join(','));
  }
  function shown(t) { return state.classFilter === 'all' || t.class === state.classFilter; }
  $('class-filter').addEventListener('change', (e) => { state.classFilter = e.target.value; render(); });
  function renderTrackList() {
    const list = $('track-list');
    list.replaceChildren();
    const tracks = [...state.tracks.values()].filter(shown).sort((a, b) => a.id - b.id);
    if (tracks.length === 0) {
      const li = document.createElement('li');
      li.className = 'hint';
      li.textContent = 'No live tracks.';
      list.appendChild(li);
    }
    for (const t of tracks) {
      const li = document.createElement('li');
      li.dataset.trackId = t.id;
      li.className = t.status + ` class-${t.class}` + (t.id === state.selected ? ' selected' : '');
      li.dataset.class = t.class;
      li.innerHTML = `<span class="id">T${t.id}</span><span class="class">${t.class}</span>` +
        `<span>${fmt(t.position_m[2], 0)} m</span>` +
        `<span>${fmt(t.speed_mps)} m/s</span><span>${fmt(t.heading_deg, 0)}°</span><span>${t.status}</span>`;
      li.addEventListener('click', () => select(t.id));
      list.appendChild(li);
    }
  }
  function renderNodes() {
    const rows = $('node-rows');
    rows.replaceChildren();
    for (const n of state.nodes) {
      const tr = document.createElement('tr');
      tr.dataset.nodeId = n.array;
      tr.dataset.nodeState = n.state;
      const s = n.status || {};
      const doa = (n.doa || [])[0];
      const cells = [
        n.array,
        n.state,
        n.status ? fmt(s.level_dbfs) : '–',
        n.status ? `${s.clipped_samples}` : '–',
        n.status ? `${s.overruns}` : '–',
        n.status ? `${s.dropouts}` : '–',
        doa ? `${fmt(doa.azimuth_deg, 0)}°/${fmt(doa.elevation_deg, 0)}°` : '–',
      ];
      // Audio health: channels (0-based mic index) with a problem on their last judgement, their
      // own audio's (silent, clipped, ...) and against the array's other channels (dead,
      // polarity flipped, level imbalance, closure, skew, swapped).
      const audio = (s.channels || [])
        .map((c, index) => (c.problems || []).length
          ? `channel ${index}: ${c.problems.map((p) => p.replaceAll('_', ' ')).join(', ')}` : '')
        .filter((text) => text);
      cells.forEach((text, i) => {
        const td = document.createElement('td');
        td.textContent = text;
        if (i === 0 && audio.length) {
          td.className = 'warn';
          td.title = `audio: ${audio.join('; ')}`;
        }
        if (i === 1) {
          td.className = 'state';
          if (n.stale_reason) td.title = `stale: ${n.stale_reason.replace('_', ' ')}` +
            (Number.isFinite(n.status_age_s) ? `, last status ${fmt(n.status_age_s)} s ago` : '');
        }
        if ((i === 3 && s.clipped_samples > 0) || (i === 4 && s.overruns > 0) ||
            (i === 5 && s.dropouts > 0)) td.className = 'warn';
        tr.appendChild(td);
      });
      rows.appendChild(tr);
      // The operator must see it without hovering: a warning line under the node, naming it.
      if (audio.length) {
        const warning = document.createElement('tr');
        warning.className = 'node-warning';
        warning.dataset.warningFor = n.array;
        const td = document.createElement('td');
        td.colSpan = cells.length;
        td.className = 'warn';
        td.textContent = `${n.array} ${audio.join('; ')}`;
        warning.appendChild(td);
        rows.appendChild(warning);
      }
    }
  }
  function renderAlerts() {
    const log = $('alert-log');
    log.replaceChildren();
    for (const a of state.alerts.slice(-50).reverse()) {
      const li = document.createElement('li');
      li.dataset.event = a.event;
      li.dataset.zone = a.zone;
      li.dataset.trackId = a.track_id;
      li.textContent = `${fmt(a.t)} s  T${a.track_id} ${a.event} ${a.zone}`;
      log.appendChild(li);
    }
    const banner = $('alert-banner');
    const a = state.bannerAlert;
    if (a && state.time - a.t <= BANNER_S) {
      banner.hidden = false;
      banner.dataset.zone = a.zone;
      banner.dataset.trackId = a.track_id;
      banner.dataset.event = a.event;
      $('alert-text').textContent = `ALERT: ${a.class || 'track'} T${a.track_id} ${a.event} zone “${a.zone}” at ${fmt(a.t)} s ` +
        `(x ${fmt(a.position_m[0])}, y ${fmt(a.position_m[1])}, alt ${fmt(a.position_m[2])} m)`;
    } else {
      banner.hidden = true;
    }
  }
  $('alert-dismiss').addEventListener('click', () => { state.bannerAlert = null; renderAlerts(); });

  let pending = false;
  function render() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => {
      pending = false;
      $('stream-time').textContent = `t = ${fmt(state.time)} s`;
      drawPlan();
      drawAltitude();
      renderSelected();
      renderTrackList();
      renderNodes();
      renderAlerts();
    });
  }

  // ---------- data ----------
  function advance(t) {
    if (Number.isFinite(t) && t > state.time) state.time = t;
  }
  function onTracks(doc) {
    advance(doc.t);
    state.tracks = new Map(doc.tracks.map((t) => [t.id, t]));
    for (const t of doc.tracks) {
      const trail = state.trails.get(t.id) || [];
      if (!trail.length || trail[trail.length - 1][0] < t.t) trail.push([t.t, ...t.position_m]);
      state.trails.set(t.id, trail);
    }
    const horizon = state.time - TRAIL_S;
    for (const [id, trail] of state.trails) {
      while (trail.length && trail[0][0] < horizon) trail.shift();
      if (!trail.length) state.trails.delete(id);
    }
    if (!state.fitted && doc.tracks.length) { state.fitted = true; fitView(); }
    render();
  }
  function onDoa(d) {
    advance(d.t);
    state.doas.set(`${d.array}/${d.source_index}`, d);
    render();
  }
  function onNodes(doc) {
    advance(doc.t);
    state.nodes = doc.nodes;
    for (const n of doc.nodes) for (const d of n.doa || []) {
      const key = `${d.array}/${d.source_index}`;
      const old = state.doas.get(key);
      if (!old || old.t < d.t) state.doas.set(key, d);
    }
    render();
  }
  const alertKey = (a) => `${a.t}/${a.zone}/${a.track_id}/${a.event}`;
  function onAlert(a) {
    if (state.alerts.some((b) => alertKey(b) === alertKey(a))) return;  // already have it
    advance(a.t);
    state.alerts.push(a);
    if (state.alerts.length > 500) state.alerts.shift();
    if (a.entered) state.bannerAlert = a;
    render();
  }
  async function getJson(path) {
    const res = await fetch(path, { cache: 'no-store' });
    if (!res.ok) throw new Error(`${path}: HTTP ${res.status}`);
    return res.json();
  }
  async function loadSnapshot() {
    const [site, history, nodes, alerts, tracks] = await Promise.all([
      getJson('/api/site'), getJson('/api/tracks/history'), getJson('/api/nodes'),
      getJson('/api/alerts'), getJson('/api/tracks')]);
    state.site = site;
    state.trails = new Map(history.tracks.map((h) => [h.id, h.points]));
    state.alerts = alerts.alerts;
    state.bannerAlert = [...alerts.alerts].reverse().find((a) => a.entered) || null;
    onNodes(nodes);
    onTracks(tracks);
    if (!state.fitted) fitView();
  }
  // Alerts sent while the stream was down never come again on it: ask for the ones since the
  // last we have (tracks and nodes are whole snapshots, the next event replaces them).
  async function catchUpAlerts() {
    const last = state.alerts.length ? state.alerts[state.alerts.length - 1].t : -1;
    const doc = await getJson(`/api/alerts?since=${encodeURIComponent(last - 1e-6)}`);
    for (const a of doc.alerts) onAlert(a);
  }
  function connect(snapshotLoaded) {
    const status = $('connection');
    const source = new EventSource('/api/stream');
    // What the page still has to read once the stream is up: the whole snapshot when it could
    // not be read at start, else the alerts of a gap. A read that fails (the network often
    // comes back in steps) is tried again while the stream stays up, so no alert is left behind.
    let behind = snapshotLoaded ? null : 'snapshot';
    let retry = null;
    const readWhatWasMissed = () => {
      retry = null;
      if (!behind || source.readyState !== EventSource.OPEN) return;
      const what = behind;
      behind = null;
      (what === 'snapshot' ? loadSnapshot() : catchUpAlerts()).catch((err) => {
        console.warn(`${what === 'snapshot' ? 'snapshot' : 'alerts'} after reconnect: ${err.message}`);
        if (behind !== 'snapshot') behind = what;
        if (!retry) retry = setTimeout(readWhatWasMissed, 1000);
      });
    };
    source.addEventListener('open', () => {
      status.dataset.state = 'live'; status.textContent = 'live';
      readWhatWasMissed();
    });
    source.addEventListener('error', () => {
      if (behind !== 'snapshot') behind = 'alerts';
      status.dataset.state = 'lost'; status.textContent = 'reconnecting…';
    });
    source.addEventListener('tracks', (e) => onTracks(JSON.parse(e.data)));
    source.addEventListener('doa', (e) => onDoa(JSON.parse(e.data)));
    source.addEventListener('nodes', (e) => onNodes(JSON.parse(e.data)));
    source.addEventListener('alert', (e) => onAlert(JSON.parse(e.data)));
  }

  loadSnapshot()
    .then(() => true, (err) => {
      $('connection').dataset.state = 'lost'; $('connection').textContent = `error: ${err.message}`;
      return false;
    })
    .then(connect);
  // Exposed for the browser test and for debugging from the console.
  window.dronetrack = { state, select, fitView };
})();
