// The view's page over meshcat's three.js viewer (window.MeshCat, from main.min.js). Every change
// to the scene goes through the viewer's public commands (handle_command: set_object,
// set_transform, set_property); this file only computes them per frame and draws the overlay.
// The transforms mirror stewart_sim/view/geometry.py (object_transforms, arrow_transforms), the colours
// stewart_sim/view/colours.py (force_colours): the browser tests hold them to each other.
(function () {
  "use strict";
  const DATA = JSON.parse(document.getElementById("view-data").textContent);
  const G = DATA.geometry;
  const LUT = DATA.lut;
  const viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
  for (const cmd of DATA.scene) viewer.handle_command(cmd);

  // --- geometry (geometry.py) -------------------------------------------------------------
  function rotation(q) {              // R = Rz(thz) Ry(thy) Rx(thx), rows
    const cx = Math.cos(q[3]), sx = Math.sin(q[3]);
    const cy = Math.cos(q[4]), sy = Math.sin(q[4]);
    const cz = Math.cos(q[5]), sz = Math.sin(q[5]);
    return [[cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
            [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
            [-sy, cy * sx, cy * cx]];
  }
  function mul(A, B) {
    const C = [[0, 0, 0], [0, 0, 0], [0, 0, 0]];
    for (let i = 0; i < 3; i++) for (let j = 0; j < 3; j++)
      for (let k = 0; k < 3; k++) C[i][j] += A[i][k] * B[k][j];
    return C;
  }
  function apply(R, p) {
    return [0, 1, 2].map(i => R[i][0] * p[0] + R[i][1] * p[1] + R[i][2] * p[2]);
  }
  function axisTo(u) {                // smallest rotation taking y onto u (Rodrigues)
    const c = u[1];
    if (c < -1 + 1e-12) return [[1, 0, 0], [0, -1, 0], [0, 0, -1]];
    const k = [u[2], 0, -u[0]];       // y x u
    const K = [[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]];
    const K2 = mul(K, K);
    const R = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
    for (let i = 0; i < 3; i++) for (let j = 0; j < 3; j++)
      R[i][j] += K[i][j] + K2[i][j] / (1 + c);
    return R;
  }
  function matrix(R, p) {             // 4x4, column by column (three.js Matrix4.fromArray)
    return [R[0][0], R[1][0], R[2][0], 0, R[0][1], R[1][1], R[2][1], 0,
            R[0][2], R[1][2], R[2][2], 0, p[0], p[1], p[2], 1];
  }
  const Y_TO_Z = [[1, 0, 0], [0, 0, -1], [0, 1, 0]];
  const mean = (a) => a.reduce((s, x) => s + x, 0) / a.length;
  const TOP = mean(G.base_joints.map(a => a[2]));
  const UNDER = mean(G.platform_joints.map(p => p[2]));
  const I3 = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];

  function objectTransforms(q) {
    const R = rotation(q);
    const x = [q[0], q[1], q[2]];
    const add = (a, b, s) => [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]];
    const half = G.plate_thickness / 2;
    const out = {
      "base": matrix(Y_TO_Z, [0, 0, TOP - half]),
      "platform": matrix(mul(R, Y_TO_Z), add(x, apply(R, [0, 0, UNDER + half]), 1)),
    };
    for (let i = 0; i < 6; i++) {
      const a = G.base_joints[i];
      const p = add(x, apply(R, G.platform_joints[i]), 1);
      const d = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
      const l = Math.hypot(d[0], d[1], d[2]);
      const u = [d[0] / l, d[1] / l, d[2] / l];
      const turn = axisTo(u);
      out[`legs/${i + 1}/cylinder`] = matrix(turn, add(a, u, G.cylinder_length / 2));
      out[`legs/${i + 1}/piston`] = matrix(turn, add(p, u, -G.piston_length / 2));
      out[`joints/base/${i + 1}`] = matrix(I3, a);
      out[`joints/platform/${i + 1}`] = matrix(I3, p);
    }
    if (G.frames) {                   // geometry.py frame_transforms
      const F = G.frames;
      out["frames/pivot"] = matrix(I3, add(x, apply(R, F.pivot), 1));
      out["frames/tool"] = matrix(mul(R, rotation(F.tool)), add(x, apply(R, F.tool.slice(0, 3)), 1));
      out["frames/user"] = matrix(rotation(F.user), F.user.slice(0, 3));
    }
    return out;
  }

  // the specific-force arrows at the head (geometry.py arrow_transforms): null for a zero force
  const CUES = ["f_vehicle", "f_delivered"];
  function arrowTransforms(q, f) {
    const R = rotation(q);
    const d = apply(R, f);
    const size = Math.hypot(d[0], d[1], d[2]);
    if (!(size > 0)) return null;
    const u = d.map(v => v / size);
    const length = size * G.arrow_scale;
    const tip = Math.min(G.arrow_tip, length);
    const h = apply(R, G.head);
    const at = (s) => [0, 1, 2].map(i => q[i] + h[i] + u[i] * s);
    const turn = axisTo(u);
    const stretch = (s) => mul(turn, [[1, 0, 0], [0, s, 0], [0, 0, 1]]);
    return {shaft: matrix(stretch(length - tip), at((length - tip) / 2)),
            tip: matrix(stretch(tip / G.arrow_tip), at(length - tip / 2))};
  }

  // --- colours (colours.py) ---------------------------------------------------------------
  function forceColour(f, scale) {
    const s = (Math.min(1, Math.max(-1, f / scale)) + 1) / 2;
    const x = s * (LUT.length - 1);
    const k = Math.min(Math.floor(x), LUT.length - 2);
    const w = x - k;
    return [0, 1, 2].map(j => LUT[k][j] * (1 - w) + LUT[k + 1][j] * w);
  }
  function niceCeiling(x) {
    if (!(x > 0 && isFinite(x))) return 1;
    const e = Math.floor(Math.log10(x));
    for (const m of [1, 2, 2.5, 5, 10]) if (m * 10 ** e >= x * (1 - 1e-12)) return m * 10 ** e;
    return 10 ** (e + 1);
  }
  let forceScale = DATA.force_scale;   // null in a live view without drive ratings: grows

  const el = (id) => document.getElementById(id);
  function drawColourBar() {
    const stops = LUT.map((c, k) => `rgb(${c.map(v => Math.round(255 * v)).join(",")}) ` +
                                    `${(100 * (1 - k / (LUT.length - 1))).toFixed(2)}%`);
    el("bar").style.background = `linear-gradient(to bottom, ${stops.reverse().join(", ")})`;
    const F = forceScale || 1;
    const fmt = (v) => (Math.abs(v) >= 100 || v === 0 ? v.toFixed(0) :
                        Math.abs(v) >= 1 ? v.toFixed(1) : v.toPrecision(2));
    el("tick-max").textContent = `+${fmt(F)} N`;
    el("tick-half").textContent = `+${fmt(F / 2)} N`;
    el("tick-zero").textContent = "0 N";
    el("tick-mhalf").textContent = `${fmt(-F / 2)} N`;
    el("tick-min").textContent = `${fmt(-F)} N`;
  }

  // --- one frame, through the viewer's commands ------------------------------------------
  const PLATE_ALPHA = DATA.plate_opacity === undefined ? 1 : DATA.plate_opacity;
  const PLATE = [...DATA.plate_rgb, PLATE_ALPHA];
  const ALARM = [0.85, 0.12, 0.12, PLATE_ALPHA];
  const cmd = (c) => viewer.handle_command(c);
  const setT = (path, m) => cmd({type: "set_transform", path: path, matrix: m});
  const setP = (path, name, v) => cmd({type: "set_property", path: path, property: name, value: v});
  const GHOST_KEYS = (k) => k === "platform" || k.startsWith("legs/");
  let shown = null;

  function atLimit(l) {
    if (!G.stroke_limits) return [false, false, false, false, false, false];
    const band = G.stroke_margin * (G.leg_max - G.leg_min);
    return l.map(v => v <= G.leg_min + band || v >= G.leg_max - band);
  }

  function show(f) {
    const T = objectTransforms(f.q);
    for (const key in T) setT(`/stewart/${key}`, T[key]);
    if (DATA.ghost) {
      const ref = f.q_ref !== null && f.q_ref !== undefined;
      setP("/ghost", "visible", ref);
      if (ref) {
        const TR = objectTransforms(f.q_ref);
        for (const key in TR) if (GHOST_KEYS(key)) setT(`/ghost/${key}`, TR[key]);
      }
    }
    const peak = Math.max(...f.forces.map(Math.abs));
    if (forceScale === null || forceScale === undefined || (DATA.live && peak > forceScale)) {
      forceScale = niceCeiling(Math.max(peak, forceScale || 0));
      drawColourBar();
    }
    const limits = f.at_limit || atLimit(f.lengths);
    for (let i = 0; i < 6; i++) {
      setP(`/stewart/legs/${i + 1}/cylinder`, "color", [...forceColour(f.forces[i], forceScale), 1]);
      setT(`/stewart/limits/${i + 1}`, T[`joints/platform/${i + 1}`]);
      setP(`/stewart/limits/${i + 1}`, "visible", !!limits[i]);
    }
    const singular = f.cond > G.cond_warn;
    setP("/stewart/platform", "color", singular ? ALARM : PLATE);
    const arrows = DATA.cues ? showCues(f) : null;
    shown = {t: f.t, q: f.q, q_ref: f.q_ref, lengths: f.lengths, forces: f.forces, cond: f.cond,
             at_limit: limits.map(Boolean), singular: singular, transforms: T, arrows: arrows,
             f_vehicle: three(f.f_vehicle) ? f.f_vehicle : null,
             f_delivered: three(f.f_delivered) ? f.f_delivered : null};
    writeText(f, limits, singular);
  }

  const three = (a) => Array.isArray(a) && a.length === 3 && a.every(finite);
  function showCues(f) {         // the arrows of the frame's specific forces; hidden when null
    const out = {};
    let any = false;
    for (const name of CUES) {
      const A = three(f[name]) ? arrowTransforms(f.q, f[name]) : null;
      setP(`/cues/${name}`, "visible", A !== null);
      if (A !== null) {
        setT(`/cues/${name}/shaft`, A.shaft);
        setT(`/cues/${name}/tip`, A.tip);
        any = true;
      }
      out[name] = A;
    }
    setP("/cues/head", "visible", any);
    if (any) {
      const h = apply(rotation(f.q), G.head);
      setT("/cues/head", matrix(I3, [0, 1, 2].map(i => f.q[i] + h[i])));
    }
    el("cue-legend").style.display = any ? "block" : "none";
    return out;
  }

  const finite = (v) => typeof v === "number" && Number.isFinite(v);
  const mm = (v) => (1000 * v).toFixed(3).padStart(9);
  const deg = (v) => (180 / Math.PI * v).toFixed(3).padStart(9);
  const pose = (q) => q.slice(0, 3).map(mm).join("") + q.slice(3).map(deg).join("");
  function writeText(f, limits, singular) {
    const lines = [
      `t = ${f.t.toFixed(3)} s`,
      "",
      "pose         x [mm]   y [mm]   z [mm] thx [deg] thy [deg] thz [deg]",
      `actual   ${pose(f.q)}`,
    ];
    if (f.q_ref !== null && f.q_ref !== undefined) lines.push(`reference${pose(f.q_ref)}`);
    lines.push("", "leg          " + [1, 2, 3, 4, 5, 6].map(i => String(i).padStart(9)).join(""));
    lines.push("length [mm]  " + f.lengths.map(mm).join(""));
    lines.push("force [N]    " + f.forces.map(v => v.toFixed(3).padStart(9)).join(""));
    const cond = finite(f.cond) ? f.cond.toPrecision(4) : "not finite";
    lines.push("", `cond(J) = ${cond}  (marked above ${G.cond_warn})`);
    if (DATA.cues && (three(f.f_vehicle) || three(f.f_delivered))) {
      const acc = (v) => three(v) ? v.map(x => x.toFixed(3).padStart(9)).join("") : "        -".repeat(3);
      lines.push("", "specific force at the head [m/s^2]      x        y        z");
      lines.push(`vehicle                          ${acc(f.f_vehicle)}`);
      lines.push(`delivered                        ${acc(f.f_delivered)}`);
    }
    el("info").textContent = lines.join("\n");
    const warn = [];
    const legs = limits.map((b, i) => b ? i + 1 : 0).filter(i => i);
    if (legs.length) warn.push(`leg${legs.length > 1 ? "s" : ""} ${legs.join(", ")} at a stroke ` +
                               `limit [${(1000 * G.leg_min).toFixed(1)}, ${(1000 * G.leg_max).toFixed(1)}] mm`);
    if (singular) warn.push(`near-singular: cond(J) = ${f.cond.toPrecision(4)} > ${G.cond_warn}`);
    el("alert").textContent = warn.join("  \u2022  ");
    el("alert").style.display = warn.length ? "block" : "none";
  }

  // --- frame sources: embedded frames (static) or a polled URL (live) --------------------
  function f32(b64) {
    const bin = atob(b64);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Float32Array(bytes.buffer);
  }
  const api = {ready: false, show: null, shown: () => shown, objectTransforms, arrowTransforms,
               forceColour, forceScale: () => forceScale, viewer};
  window.stewartView = api;
  function ready() {        // after the viewer has rendered the first frame
    requestAnimationFrame(() => requestAnimationFrame(() => { api.ready = true; }));
  }

  if (DATA.cues) {        // the arrows' legend: their colours and scale
    for (const name of CUES)
      el(`cue-dot-${name}`).style.background =
        `rgb(${DATA.cue_rgb[name].map(v => Math.round(255 * v)).join(",")})`;
    el("cue-scale").textContent = `arrows: 1 m/s\u00b2 = ${(1000 * G.arrow_scale).toPrecision(3)} mm` +
                                  ` (1 g = ${(9.81 * G.arrow_scale).toPrecision(3)} m)`;
  }

  function drawable(s) {
    const six = (a) => Array.isArray(a) && a.length === 6 && a.every(finite);
    return finite(s.t) && six(s.q) && six(s.lengths) && six(s.forces) &&
           (s.q_ref === null || s.q_ref === undefined || six(s.q_ref)) &&
           (s.cond === null || finite(s.cond));
  }

  if (DATA.live) {
    el("player").style.display = "none";
    drawColourBar();
    let failures = 0;
    async function poll() {
      try {
        const r = await fetch(DATA.live.state_url, {cache: "no-store"});
        if (!r.ok) throw new Error(`HTTP ${r.status}`);
        const state = await r.json();
        const where = `live: ${DATA.live.state_url}` +
                      (state.armed === undefined ? "" : state.armed ? " (armed)" : " (disarmed)");
        if (drawable(state)) {
          show(state);
          el("status").textContent = where;
        } else {
          // /state sends a non-finite number as null: keep the last good picture, say why
          el("status").textContent = state.t === null ? `${where}: no state from the device yet`
                                     : `${where}: state at t = ${state.t} not finite, not drawn`;
        }
        failures = 0;
        if (!api.ready) ready();
      } catch (e) {
        failures += 1;
        el("status").textContent = `live: waiting for ${DATA.live.state_url} (${e.message})`;
      }
      setTimeout(poll, failures ? 500 : DATA.live.period_ms);
    }
    poll();
  } else {
    const F = DATA.frames;
    const n = F.count;
    const t = f32(F.t), q = f32(F.q), ln = f32(F.lengths), fo = f32(F.forces), co = f32(F.cond);
    const qr = F.q_ref ? f32(F.q_ref) : null;
    const fv = F.f_vehicle ? f32(F.f_vehicle) : null, fd = F.f_delivered ? f32(F.f_delivered) : null;
    const vec = (a, k) => a ? Array.from(a.subarray(3 * k, 3 * k + 3)) : null;
    const lim = Uint8Array.from(atob(F.at_limit), c => c.charCodeAt(0));
    const six = (a, k) => Array.from(a.subarray(6 * k, 6 * k + 6));
    const frame = (k) => ({t: t[k], q: six(q, k), q_ref: qr ? six(qr, k) : null,
                           lengths: six(ln, k), forces: six(fo, k), cond: co[k],
                           at_limit: Array.from(lim.subarray(6 * k, 6 * k + 6)),
                           f_vehicle: vec(fv, k), f_delivered: vec(fd, k)});
    if (DATA.meta.speed) el("speed").value = String(DATA.meta.speed);
    const slider = el("slider");
    slider.max = n - 1;
    let k = 0, playing = false, clock = 0, last = null;
    // the chapters (meta.chapters: label, start time): the selector plays one in a loop
    const chapters = DATA.meta.chapters || [];
    const pick = el("chapter");
    let loop = null;                  // {c, first, t0, t1}: the chapter played in a loop
    function chapterAt(i) {
      let c = -1;
      chapters.forEach((ch, j) => { if (t[i] >= ch.t - 1e-6) c = j; });
      return c;
    }
    function chapterLoop(c) {
      let first = 0;
      while (first + 1 < n && t[first] < chapters[c].t - 1e-6) first++;
      const end = c + 1 < chapters.length ? chapters[c + 1].t
                                          : t[n - 1] + (n > 1 ? t[n - 1] - t[n - 2] : 1);
      return {c, first, t0: t[first], t1: end};
    }
    if (chapters.length) {
      pick.add(new Option("all, in turn", "-1"));
      chapters.forEach((ch, j) => pick.add(new Option(ch.label, String(j))));
      pick.style.display = "";
    }
    function go(i) {
      k = Math.max(0, Math.min(n - 1, i));
      slider.value = k;
      const c = chapters.length ? chapterAt(k) : -1;
      el("time").textContent = `${t[k].toFixed(3)} / ${t[n - 1].toFixed(3)} s` +
                               (c >= 0 ? ` \u00b7 ${chapters[c].label}` : "");
      if (chapters.length) pick.value = String(loop ? loop.c : -1);
      show(frame(k));
    }
    api.show = go;
    api.frames = n;
    api.times = t;
    function tick(now) {
      if (!playing) return;
      if (last !== null) clock += (now - last) / 1000 * Number(el("speed").value);
      last = now;
      let j = k;
      if (loop && clock >= loop.t1) {
        clock = loop.t0 + (clock - loop.t1) % (loop.t1 - loop.t0);
        j = loop.first;
      }
      while (j + 1 < n && t[j + 1] <= clock) j++;
      if (j !== k) go(j);
      if (!loop && k >= n - 1) { setPlaying(false); return; }
      requestAnimationFrame(tick);
    }
    function setPlaying(p) {
      playing = p;
      el("play").textContent = p ? "\u23F8 pause" : "\u25B6 play";
      if (p) {
        if (k >= n - 1) go(0);
        clock = t[k]; last = null;
        requestAnimationFrame(tick);
      }
    }
    el("play").addEventListener("click", () => setPlaying(!playing));
    slider.addEventListener("input", () => {
      setPlaying(false); loop = null; go(Number(slider.value));
    });
    pick.addEventListener("change", () => {
      const c = Number(pick.value);
      setPlaying(false);
      loop = c >= 0 ? chapterLoop(c) : null;
      go(loop ? loop.first : 0);
      setPlaying(true);
    });
    drawColourBar();
    go(0);
    ready();
  }
})();
