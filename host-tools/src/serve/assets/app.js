// dollop dashboard: plain JavaScript, no build step. Talks to the server's /api (JSON,
// multipart uploads, server-sent events) and draws the toolpath, plots and boards.
"use strict";

const COLOURS = ["#7a4824", "#ecbe46", "#3a7bd5", "#d64545", "#46a05a", "#8c50aa", "#f08228", "#787878"];
const $ = (id) => document.getElementById(id);
const el = (tag, attrs = {}, ...kids) => {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") e.className = v;
    else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else e.setAttribute(k, v);
  }
  for (const k of kids) e.append(k);
  return e;
};

// Which tab this is (one tab commands a board at a time).
const TAB = sessionStorage.getItem("dollop-tab") || (Math.random().toString(36).slice(2) + Date.now().toString(36));
sessionStorage.setItem("dollop-tab", TAB);

const app = {
  info: null,
  files: [],          // File objects chosen for the design
  config: null,       // {text, fields, derived}
  configOriginal: {}, // path -> raw as loaded, to find edits
  job: null,          // {id, figures, toolpath, materials}
  sim: null,          // sim id
  jobs: {},           // id -> toolpath (for boards)
  trend: {},          // board id -> [{unix_ms, speed, flow, line_kpa}], the last minutes
  consoleSeq: null,   // the console's newest line number shown
};

function toast(msg, bad) {
  const t = $("toast");
  t.textContent = msg;
  t.className = bad ? "bad" : "";
  t.hidden = false;
  clearTimeout(toast.timer);
  toast.timer = setTimeout(() => (t.hidden = true), bad ? 9000 : 4000);
}

function showError(id, msg) {
  const e = $(id);
  e.textContent = msg || "";
  e.hidden = !msg;
}

// An error the server tied to one of the page's inputs (its id): marked there until edited.
function markField(err) {
  const input = err && err.field ? document.getElementById(err.field) : null;
  if (!input) return;
  input.classList.add("bad-input");
  input.addEventListener("input", () => input.classList.remove("bad-input"), { once: true });
  const details = input.closest("details");
  if (details) details.open = true;
}

async function api(path, opts = {}) {
  let r;
  try {
    r = await fetch(path, opts);
  } catch (e) {
    throw new Error("the dashboard server does not answer (is dollop serve still running?)");
  }
  if (r.status === 401) {
    // The dashboard asks for its key (dollop serve --auth) and this browser has none now.
    location.href = "/login";
    throw new Error("sign in first");
  }
  const type = r.headers.get("content-type") || "";
  const body = type.includes("json") ? await r.json() : await r.text();
  if (!r.ok) {
    const err = new Error(typeof body === "object" ? body.error : (r.status === 413 ? `the upload is larger than the ${app.info ? app.info.max_upload_mb : 64} MiB limit` : body || r.statusText));
    err.field = typeof body === "object" ? body.field : undefined;
    err.status = r.status;
    throw err;
  }
  return body;
}

const postJson = (path, obj) => api(path, { method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(obj) });

// ---------------------------------------------------------------- navigation
function showPage(name) {
  for (const b of document.querySelectorAll("nav .tab")) b.classList.toggle("active", b.dataset.page === name);
  for (const p of document.querySelectorAll(".page")) p.hidden = p.id !== "page-" + name;
  if (name === "design") drawPreview();
  if (name === "files") loadFiles();
  if (name === "print") for (const id of Object.keys(app.trend)) drawTrend(Number(id));
}
for (const b of document.querySelectorAll("nav .tab")) b.addEventListener("click", () => showPage(b.dataset.page));

// ---------------------------------------------------------------- design files
function setFiles(list) {
  app.files = Array.from(list);
  const ul = $("design-list");
  ul.replaceChildren(...app.files.map((f, i) => el("li", {}, `${f.name} (${(f.size / 1024).toFixed(1)} KiB)` + (app.files.length > 1 ? ` → inlet ${i}` : ""))));
}
$("design-files").addEventListener("change", (e) => setFiles(e.target.files));
// Files dragged from the desktop onto `zone` go to `take` (the designs, the camera frames).
function dropZone(zone, take) {
  zone.addEventListener("dragover", (e) => { e.preventDefault(); zone.classList.add("over"); });
  zone.addEventListener("dragleave", () => zone.classList.remove("over"));
  zone.addEventListener("drop", (e) => {
    e.preventDefault();
    zone.classList.remove("over");
    if (e.dataTransfer.files.length) take(e.dataTransfer.files);
  });
}
dropZone($("drop"), setFiles);

async function useBundled(names) {
  const files = [];
  for (const n of names) {
    const i = app.info.designs.indexOf(n);
    const r = await fetch(`/api/designs/${i}`);
    files.push(new File([await r.blob()], n));
  }
  setFiles(files);
}

// ---------------------------------------------------------------- config
function renderConfig(c) {
  app.config = c;
  app.configOriginal = {};
  const box = $("config-fields");
  box.replaceChildren();
  for (const f of c.fields) {
    app.configOriginal[f.path] = f.raw;
    const input = el("input", { name: f.path, value: f.raw, id: "cfg-" + f.path });
    box.append(el("div", { class: "field", "data-path": f.path }, el("label", { for: "cfg-" + f.path }, f.path), input, el("div", { class: "field-error" })));
  }
  renderDerived(c.derived);
}

function renderDerived(figs) {
  $("config-derived").replaceChildren(...figs.map(([k, v]) => el("tr", {}, el("td", {}, k), el("td", {}, v))));
}

function clearFieldErrors() {
  for (const f of document.querySelectorAll(".field")) {
    f.classList.remove("has-error");
    f.querySelector(".field-error").textContent = "";
  }
  showError("config-error", "");
}

function showConfigError(err) {
  clearFieldErrors();
  const row = err.field && document.querySelector(`.field[data-path="${CSS.escape(err.field)}"]`);
  if (row) {
    row.classList.add("has-error");
    row.querySelector(".field-error").textContent = err.message;
    $("config-details").open = true;
    row.scrollIntoView({ block: "nearest" });
  }
  showError("config-error", "Config: " + err.message);
  $("config-derived").replaceChildren();
}

function edits() {
  const out = [];
  for (const input of document.querySelectorAll("#config-fields input")) {
    if (input.value !== app.configOriginal[input.name]) out.push({ path: input.name, raw: input.value });
  }
  return out;
}

// Checks the config with the edits; returns its text, or null (errors shown).
async function checkConfig() {
  if (!app.config) return null;
  try {
    const c = await postJson("/api/config/check", { text: app.config.text, edits: edits() });
    const keep = edits();
    clearFieldErrors();
    renderDerived(c.derived);
    if (keep.length) {
      // The checked text becomes the base; the inputs keep what was typed.
      renderConfig(c);
    }
    app.config = c;
    return c.text;
  } catch (e) {
    showConfigError(e);
    return null;
  }
}

// `i`: a bundled or --config config's number, or "saved:NAME" for one saved by name.
async function loadConfig(i) {
  try {
    const saved = String(i).startsWith("saved:");
    renderConfig(await api(saved ? `/api/saved-configs/${encodeURIComponent(String(i).slice(6))}` : `/api/configs/${i}`));
    clearFieldErrors();
    localStorage.setItem("dollop-config", String(i));
    $("config-name").value = saved ? String(i).slice(6).replace(/\.toml$/, "") : "";
  } catch (e) {
    showConfigError(e);
  }
}
$("config-select").addEventListener("change", (e) => loadConfig(e.target.value));

// The configs saved by name, after the bundled ones in the list.
async function listSavedConfigs() {
  const sel = $("config-select");
  for (const o of Array.from(sel.options)) if (o.value.startsWith("saved:")) o.remove();
  let r;
  try { r = await api("/api/saved-configs"); } catch (_) { return; }
  for (const c of r.configs) sel.append(el("option", { value: "saved:" + c.name }, `${c.name.replace(/\.toml$/, "")} (saved)`));
}

// Writes the config on the page (edits included) under `name`; the list then selects it.
async function saveConfig(name, text) {
  const r = await api(`/api/saved-configs/${encodeURIComponent(name)}`, { method: "PUT", headers: { "content-type": "application/json" }, body: JSON.stringify({ text }) });
  await listSavedConfigs();
  $("config-select").value = "saved:" + r.name;
  localStorage.setItem("dollop-config", "saved:" + r.name);
  return r;
}
$("config-save").addEventListener("click", async () => {
  const name = $("config-name").value.trim();
  if (!name) return toast("Give the config a name to save it under.", true);
  const text = await checkConfig();
  if (!text) return;
  try {
    const r = await saveConfig(name, text);
    toast(r.message);
  } catch (e) { toast(e.message, true); }
});
$("config-check").addEventListener("click", async () => {
  if (await checkConfig()) toast("The config is valid.");
});

// ---------------------------------------------------------------- slicing
function sliceOptions() {
  const o = {};
  const num = ["width_mm", "height_mm", "layers", "threshold", "background_tolerance", "prime_mm", "min_run_mm", "connect_mm"];
  for (const k of num) {
    const v = $("opt-" + k).value.trim();
    if (v !== "") o[k] = Number(v);
  }
  for (const k of ["rotate", "mirror", "palette", "background", "origin"]) {
    const v = $("opt-" + k).value.trim();
    if (v !== "") o[k] = v;
  }
  o.invert = $("opt-invert").checked;
  o.markers = $("opt-markers").checked;
  o.calibration_pattern = $("opt-calibration_pattern").checked;
  return o;
}

// Posts a multipart form with upload progress (fetch has none).
function upload(path, form, bar) {
  return new Promise((resolve, reject) => {
    const x = new XMLHttpRequest();
    x.open("POST", path);
    bar.hidden = false;
    bar.value = 0;
    x.upload.onprogress = (e) => { if (e.lengthComputable) bar.value = e.loaded / e.total; };
    x.onload = () => {
      bar.hidden = true;
      let body = null;
      try { body = JSON.parse(x.responseText); } catch (_) { body = null; }
      if (x.status >= 200 && x.status < 300 && body) return resolve(body);
      let msg = body && body.error ? body.error : x.responseText || x.statusText;
      if (x.status === 413) msg = `the upload is over this dashboard's ${app.info.max_upload_mb} MiB limit; use the command line (dollop slice) for bigger files`;
      const err = new Error(msg);
      if (body) err.field = body.field;
      reject(err);
    };
    x.onerror = () => { bar.hidden = true; reject(new Error("the upload did not reach the server (connection lost, or the file is over the size limit)")); };
    x.send(form);
  });
}

$("slice").addEventListener("click", async () => {
  showError("slice-error", "");
  if (!app.files.length && !$("opt-calibration_pattern").checked) return showError("slice-error", "Choose a design first: an image, one STL per material, or a 3MF (or tick Calibration pattern).");
  const text = await checkConfig();
  if (!text) return showError("slice-error", "Fix the config first (see the field marked in red).");
  const form = new FormData();
  for (const f of app.files) form.append("design", f, f.name);
  form.append("config", text);
  form.append("options", JSON.stringify(sliceOptions()));
  const b = $("slice");
  b.disabled = true;
  b.textContent = "Slicing…";
  try {
    const job = await upload("/api/slice", form, $("upload-progress"));
    setJob(job);
    // What a reload opens again: the kept job and the options it was sliced with.
    if (job.kept) localStorage.setItem("dollop-design", JSON.stringify({ kept: job.kept, options: sliceOptions() }));
    toast("Sliced.");
  } catch (e) {
    // A config path goes to the config editor; a slicing option's input is marked.
    if (e.field && !document.getElementById(e.field)) showConfigError(e);
    showError("slice-error", e.message);
    markField(e);
  } finally {
    b.disabled = false;
    b.textContent = "Slice";
  }
});

function fmtTime(s) {
  if (s == null || !isFinite(s)) return "–";
  s = Math.round(s);
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), r = s % 60;
  return h ? `${h} h ${m} min` : m ? `${m} min ${r} s` : `${r} s`;
}

function setJob(job) {
  app.job = job;
  app.jobs[job.id] = job;
  app.sim = null;
  const f = job.figures;
  $("job-name").textContent = `job ${job.id}: ${f.name}`;
  $("job-figures").replaceChildren(...[
    ["design", f.name],
    ["size", `${f.size_mm[0].toFixed(1)} × ${f.size_mm[1].toFixed(1)} mm, ${f.layers} layer(s)`],
    ["print segments", f.segments],
    ["material switches", f.switches],
    ["beads", f.beads],
    ["printed / travel", `${f.print_mm.toFixed(0)} mm / ${f.travel_mm.toFixed(0)} mm`],
    ["job file", `${f.job_bytes} bytes`],
    ["estimated print time", `${fmtTime(f.est_time_s)} (from ${f.est_time_from}; lengths over speeds alone: ${fmtTime(f.length_time_s)})`],
  ].map(([k, v]) => el("tr", {}, el("td", {}, k), el("td", { class: "fig-" + k.replace(/\W+/g, "-") }, String(v)))));
  const sel = $("layer-select");
  sel.replaceChildren(el("option", { value: "all" }, "all"));
  for (let l = 0; l < job.toolpath.layers; l++) sel.append(el("option", { value: String(l) }, String(l)));
  $("legend").replaceChildren(...job.materials.map((m, i) => el("span", {}, el("i", { style: `background:${COLOURS[i % 8]}` }), `${i}: ${m}`)));
  $("job-downloads").replaceChildren(
    el("a", { href: `/api/jobs/${job.id}/job.dlp`, id: "dl-job" }, "job (.dlp)"),
    el("a", { href: `/api/jobs/${job.id}/job.gcode`, id: "dl-gcode" }, "G-code"),
    el("a", { href: `/api/jobs/${job.id}/preview.png` }, "toolpath picture"),
    el("a", { href: `/api/jobs/${job.id}/config.toml` }, "machine config"),
  );
  view.fit = true;
  drawPreview();
  $("sim-report").textContent = "";
  $("heatmap").removeAttribute("src");
  $("sim-progress").value = 0;
  $("sim-status").textContent = "";
  renderBoards(lastBoards);
}

// ---------------------------------------------------------------- toolpath drawing
const view = { scale: 1, ox: 0, oy: 0, fit: true };

function fitView(canvas, tp, v) {
  const [x0, y0, x1, y1] = tp.bounds;
  const m = tp.bead_mm * 2 + 1;
  const w = x1 - x0 + 2 * m, h = y1 - y0 + 2 * m;
  v.scale = Math.min(canvas.width / w, canvas.height / h);
  v.ox = (canvas.width - (x1 - x0) * v.scale) / 2 - x0 * v.scale;
  v.oy = (canvas.height + (y1 - y0) * v.scale) / 2 + y0 * v.scale;
  v.fit = false;
}

// Draws toolpath `tp` on `canvas`; layer filter; `done` = commands finished (print view).
function drawToolpath(canvas, tp, v, layer, done) {
  const g = canvas.getContext("2d");
  g.setTransform(1, 0, 0, 1, 0, 0);
  g.clearRect(0, 0, canvas.width, canvas.height);
  if (!tp) return;
  if (v.fit) fitView(canvas, tp, v);
  const X = (x) => x * v.scale + v.ox, Y = (y) => v.oy - y * v.scale;
  g.lineCap = "round";
  g.lineJoin = "round";
  const bead = Math.max(tp.bead_mm * v.scale, 1);
  for (let pass = 0; pass < 2; pass++) {
    tp.paths.forEach((p, i) => {
      if (layer !== "all" && p.l !== Number(layer)) return;
      const travel = p.m < 0;
      if ((pass === 0) === travel) return; // beads first, travel dashed on top
      const finished = done == null || tp.ends[i] <= done;
      const started = done == null || tp.starts[i] < done;
      g.beginPath();
      g.moveTo(X(p.p[0]), Y(p.p[1]));
      for (let k = 2; k < p.p.length; k += 2) g.lineTo(X(p.p[k]), Y(p.p[k + 1]));
      if (travel) {
        g.setLineDash([4, 4]);
        g.lineWidth = 1;
        g.strokeStyle = done == null || finished ? "rgba(40,40,40,.7)" : "rgba(40,40,40,.15)";
      } else {
        g.setLineDash([]);
        g.lineWidth = bead;
        g.strokeStyle = COLOURS[p.m % 8];
        g.globalAlpha = finished || started ? 1 : 0.15;
      }
      g.stroke();
      g.globalAlpha = 1;
    });
  }
  g.setLineDash([]);
}

function drawPreview() {
  const c = $("preview");
  drawToolpath(c, app.job && app.job.toolpath, view, $("layer-select").value, null);
}
$("layer-select").addEventListener("change", drawPreview);
$("zoom-reset").addEventListener("click", () => { view.fit = true; drawPreview(); });

// Wheel zooms about the pointer, drag pans.
function zoomPan(canvas, v, redraw) {
  const pos = (e) => {
    const r = canvas.getBoundingClientRect();
    return [(e.clientX - r.left) * canvas.width / r.width, (e.clientY - r.top) * canvas.height / r.height];
  };
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    const [px, py] = pos(e);
    const k = Math.exp(-e.deltaY * 0.0015);
    v.ox = px - (px - v.ox) * k;
    v.oy = py - (py - v.oy) * k;
    v.scale *= k;
    redraw();
  }, { passive: false });
  let drag = null;
  canvas.addEventListener("pointerdown", (e) => { drag = pos(e); canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const p = pos(e);
    v.ox += p[0] - drag[0];
    v.oy += p[1] - drag[1];
    drag = p;
    redraw();
  });
  canvas.addEventListener("pointerup", () => (drag = null));
}
zoomPan($("preview"), view, drawPreview);

// ---------------------------------------------------------------- simulate
$("simulate").addEventListener("click", async () => {
  showError("sim-error", "");
  if (!app.job) return showError("sim-error", "Slice a design first (Design page).");
  const b = $("simulate");
  b.disabled = true;
  $("sim-report").textContent = "";
  $("heatmap").removeAttribute("src");
  $("sim-status").textContent = "running…";
  try {
    const { sim } = await postJson(`/api/jobs/${app.job.id}/simulate`, {});
    app.sim = sim;
    const es = new EventSource(`/api/sims/${sim}/events`);
    es.addEventListener("progress", (e) => {
      $("sim-progress").value = Number(e.data);
      $("sim-status").textContent = `${(Number(e.data) / 10).toFixed(1)} %`;
    });
    es.addEventListener("done", async () => {
      es.close();
      $("sim-progress").value = 1000;
      await showSim(sim);
      b.disabled = false;
    });
    es.addEventListener("failed", (e) => {
      es.close();
      showError("sim-error", "The simulation failed: " + e.data);
      $("sim-status").textContent = "";
      b.disabled = false;
    });
    es.onerror = () => {
      if (es.readyState === EventSource.CLOSED) b.disabled = false;
    };
  } catch (e) {
    showError("sim-error", e.message);
    b.disabled = false;
  }
});

async function showSim(sim) {
  try {
    const r = await api(`/api/sims/${sim}`);
    $("sim-report").textContent = r.report;
    const f = r.figures;
    $("sim-status").textContent = `done: ${f.state}, ${fmtTime(f.time_s)} of printing` + (f.fault ? `, fault: ${f.fault}` : "");
    $("heatmap").src = `/api/sims/${sim}/heatmap.png`;
    $("heatmap").hidden = false;
    $("heatmap-none").hidden = true;
    $("sim-downloads").replaceChildren(
      el("a", { href: `/api/jobs/${app.job.id}/job.dlp` }, "job (.dlp)"),
      el("a", { href: `/api/jobs/${app.job.id}/job.gcode` }, "G-code"),
      el("a", { href: `/api/sims/${sim}/trace.csv`, id: "dl-trace" }, "trace (CSV)"),
      el("a", { href: `/api/sims/${sim}/heatmap.png`, download: `heatmap-${sim}.png` }, "heatmap picture"),
      el("a", { href: `/api/jobs/${app.job.id}/preview.png` }, "toolpath picture"),
      el("a", { href: `/api/sims/${sim}/report.txt` }, "report"),
    );
    setSeries(r.series);
  } catch (e) {
    showError("sim-error", e.message);
  }
}

// ---------------------------------------------------------------- plots
const plot = { series: null, t0: 0, t1: 1 };

function setSeries(s) {
  plot.series = s;
  plot.t0 = 0;
  plot.t1 = s.t.length ? s.t[s.t.length - 1] : 1;
  drawPlots();
}

// Axis ticks at 1, 2 or 5 times a power of ten, about `n` of them over lo..hi.
function niceTicks(lo, hi, n) {
  const raw = (hi - lo) / Math.max(n, 1);
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((m) => m * p).find((s) => s >= raw) || 10 * p;
  const out = [];
  for (let v = Math.ceil(lo / step - 1e-9) * step; v <= hi + step * 1e-9; v += step) out.push(Math.abs(v) < step * 1e-6 ? 0 : v);
  return { ticks: out, step };
}

// A tick's label: as many decimals as the step needs, never exponent noise (2.54e-43).
function tickLabel(v, step) {
  const d = Math.max(0, Math.min(6, -Math.floor(Math.log10(step) + 1e-9)));
  return v.toFixed(d);
}

// `src`: the series and time window (the Simulate page's, or a board's trend).
function drawPlot(canvas, title, unit, lines, intTicks, src = plot) {
  const g = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height, L = 60, R = 10, T = 18, B = 20;
  g.clearRect(0, 0, W, H);
  const s = src.series;
  if (!s || !s.t.length) return;
  const { t0, t1 } = src;
  let lo = Infinity, hi = -Infinity;
  for (const ln of lines) for (let i = 0; i < s.t.length; i++) {
    if (s.t[i] < t0 || s.t[i] > t1) continue;
    const v = ln.y[i];
    if (isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  }
  if (!isFinite(lo)) { lo = 0; hi = 1; }
  // Numerical dust (a pressure of 1e-43 kPa) is zero.
  if (Math.abs(lo) < 1e-9) lo = 0;
  if (Math.abs(hi) < 1e-9) hi = 0;
  if (hi - lo < 1e-9) { hi = lo + 1; }
  const yt = intTicks ? { ticks: intTicks, step: 1 } : niceTicks(lo, hi, Math.max(2, Math.floor((H - T - B) / 30)));
  if (!intTicks) { lo = Math.min(lo, yt.ticks[0]); hi = Math.max(hi, yt.ticks[yt.ticks.length - 1]); }
  const X = (t) => L + (t - t0) / (t1 - t0) * (W - L - R);
  const Y = (v) => H - B - (v - lo) / (hi - lo) * (H - T - B);
  g.font = "12px sans-serif";
  g.fillStyle = "#333";
  g.fillText(`${title} (${unit})`, L, 12);
  g.fillStyle = "#777";
  g.strokeStyle = "#eee";
  g.textAlign = "right";
  for (const v of yt.ticks) {
    if (v < lo - 1e-9 || v > hi + 1e-9) continue;
    g.beginPath(); g.moveTo(L, Y(v)); g.lineTo(W - R, Y(v)); g.stroke();
    g.fillText(intTicks ? String(v) : tickLabel(v, yt.step), L - 4, Y(v) + 4);
  }
  g.textAlign = "center";
  const xt = niceTicks(t0, t1, Math.max(2, Math.floor((W - L - R) / 110)));
  for (const t of xt.ticks) {
    g.beginPath(); g.moveTo(X(t), T); g.lineTo(X(t), H - B); g.stroke();
    g.fillText(`${tickLabel(t, xt.step)} s`, X(t), H - 4);
  }
  g.textAlign = "left";
  g.strokeStyle = "#ccc";
  g.strokeRect(L, T, W - L - R, H - T - B);
  for (const ln of lines) {
    g.strokeStyle = ln.colour;
    g.lineWidth = 1.2;
    g.beginPath();
    let first = true;
    for (let i = 0; i < s.t.length; i++) {
      if (s.t[i] < t0 && (i + 1 >= s.t.length || s.t[i + 1] < t0)) continue;
      if (s.t[i] > t1 && i > 0 && s.t[i - 1] > t1) break;
      const v = ln.y[i];
      if (!isFinite(v)) continue;
      if (first) { g.moveTo(X(s.t[i]), Y(v)); first = false; } else g.lineTo(X(s.t[i]), Y(v));
    }
    g.stroke();
  }
  let x = L + 200;
  for (const ln of lines) {
    if (!ln.name) continue;
    g.fillStyle = ln.colour;
    g.fillText(ln.name, x, 12);
    x += g.measureText(ln.name).width + 16;
  }
}

function drawPlots() {
  const s = plot.series;
  if (!s) return;
  drawPlot($("plot-speed"), "head speed", "mm/s", [{ y: s.speed, colour: "#2f6f5e" }]);
  drawPlot($("plot-flow"), "flow", "mm³/s", [{ y: s.flow, colour: "#3a7bd5" }]);
  drawPlot($("plot-pressure"), "line pressure", "kPa", s.pressure.map((p, i) => ({ y: p, colour: COLOURS[i % 8], name: `${i}: ${s.materials[i]}` })));
  drawPlot($("plot-valves"), "valves open", "inlet", s.materials.map((m, i) => ({ y: s.valves.map((v) => (v >> i) & 1 ? i + 0.8 : i), colour: COLOURS[i % 8], name: `${i}` })), s.materials.map((m, i) => i));
}

for (const c of document.querySelectorAll("canvas.plot")) {
  const tAt = (e) => {
    const r = c.getBoundingClientRect();
    const x = (e.clientX - r.left) * c.width / r.width;
    return plot.t0 + (x - 60) / (c.width - 70) * (plot.t1 - plot.t0);
  };
  c.addEventListener("wheel", (e) => {
    e.preventDefault();
    const t = tAt(e), k = Math.exp(e.deltaY * 0.0015);
    plot.t0 = t - (t - plot.t0) * k;
    plot.t1 = t + (plot.t1 - t) * k;
    drawPlots();
  }, { passive: false });
  let drag = null;
  c.addEventListener("pointerdown", (e) => { drag = tAt(e); c.setPointerCapture(e.pointerId); });
  c.addEventListener("pointermove", (e) => {
    if (drag == null) return;
    const d = drag - tAt(e);
    plot.t0 += d;
    plot.t1 += d;
    drawPlots();
  });
  c.addEventListener("pointerup", () => (drag = null));
  c.addEventListener("dblclick", () => { if (plot.series) setSeries(plot.series); });
}

// ---------------------------------------------------------------- boards
let lastBoards = null;
const boardViews = {}; // board id -> zoom state of its canvas

async function boardAction(id, action, extra = {}, force = false) {
  // Home, jog and valve tests on a board without a config load the Design page's.
  if (["home", "jog", "valve"].includes(action) && app.config) extra = { ...extra, config: app.config.text };
  try {
    const r = await postJson(`/api/boards/${id}/${action}`, { tab: TAB, force, ...extra });
    toast(r.message);
  } catch (e) {
    if (e.status === 409 && /another tab/.test(e.message)) {
      const card = document.querySelector(`.board[data-board="${id}"]`);
      if (card) card.querySelector(".board-msg").textContent = e.message;
    }
    toast(e.message, true);
  }
}

async function toolpathOf(jobId) {
  if (app.jobs[jobId]) return app.jobs[jobId];
  try {
    app.jobs[jobId] = await api(`/api/jobs/${jobId}`);
  } catch (_) {
    app.jobs[jobId] = { toolpath: null };
  }
  return app.jobs[jobId];
}

function boardCard(b) {
  const id = b.id;
  const btn = (label, action, extra) => el("button", { "data-action": action, onclick: () => boardAction(id, action, extra ? extra() : {}) }, label);
  const axis = el("select", { class: "jog-axis" }, el("option", {}, "x"), el("option", {}, "y"), el("option", {}, "z"));
  const mm = el("input", { class: "num jog-mm", type: "number", step: "any", value: "10" });
  const inlet = el("select", { class: "valve-inlet" }, ...[0, 1, 2, 3].map((i) => el("option", {}, String(i))));
  const secs = el("input", { class: "num valve-secs", type: "number", step: "any", value: "1", min: "0.1", max: "10" });
  const canvas = el("canvas", { width: "420", height: "300", class: "board-canvas" });
  const trend = el("div", { class: "trend" }, ...["speed", "flow", "pressure"].map((k) => el("canvas", { width: "600", height: "110", class: "trend-plot", "data-trend": k })));
  loadTrend(id);
  boardViews[id] = { scale: 1, ox: 0, oy: 0, fit: true };
  zoomPan(canvas, boardViews[id], () => drawBoard(id));
  const card = el("div", { class: "board", "data-board": String(id) },
    el("div", { class: "info" },
      el("h3", {}, `${b.name} `, el("span", { class: "muted small" }, b.port)),
      el("div", {}, "State: ", el("span", { class: "state" }), " ", el("span", { class: "muted small seq" })),
      el("div", { class: "fault", hidden: "" }),
      el("div", { class: "board-msg muted" }),
      el("div", { class: "job-line" }),
      el("div", { class: "progress-row" }, el("progress", { max: "1", value: "0", class: "print-progress" })),
      el("div", { class: "live" }),
      el("div", { class: "upload-row", hidden: "" }, "Upload to the board: ", el("progress", { max: "1", value: "0", class: "upload-progress" }), el("span", { class: "upload-text" })),
      el("div", { class: "controls" },
        el("button", { class: "primary", "data-action": "send", onclick: () => app.job ? boardAction(id, "send", { job: app.job.id }) : toast("Slice a design first (Design page).", true) }, "Send current job"),
        btn("Start next", "start-next"), btn("Pause", "pause"), btn("Park", "park"), btn("Resume", "resume"), btn("Abort", "abort"), btn("Home", "home")),
      el("div", { class: "controls" }, "Jog ", axis, mm, " mm ", btn("Jog", "jog", () => ({ axis: axis.value, mm: Number(mm.value) })),
        " Valve test: inlet ", inlet, " for ", secs, " s ", btn("Open", "valve", () => ({ inlet: Number(inlet.value), seconds: Number(secs.value) }))),
      el("div", { class: "controls" }, el("button", { class: "take", onclick: () => boardAction(id, "claim", {}, true), hidden: "" }, "Take control")),
      el("div", { class: "queue" }),
      trend),
    canvas);
  return card;
}

const trails = {}; // board id -> recent head positions

// A latency in ms, or a dash while it has not happened yet.
function fmtMs(ms) {
  return ms === null || ms === undefined ? "–" : `${ms.toFixed(0)} ms`;
}

async function drawBoard(id) {
  const b = lastBoards && lastBoards.boards[id];
  const card = document.querySelector(`.board[data-board="${id}"]`);
  if (!b || !card) return;
  const canvas = card.querySelector("canvas.board-canvas");
  const job = b.job ? await toolpathOf(b.job.job) : null;
  const tp = job && job.toolpath;
  const v = boardViews[id];
  drawToolpath(canvas, tp, v, "all", b.job ? b.command : 0);
  if (!tp) return;
  const g = canvas.getContext("2d");
  const X = (x) => x * v.scale + v.ox, Y = (y) => v.oy - y * v.scale;
  g.fillStyle = b.valves ? "#c0392b" : "#333";
  g.beginPath();
  g.arc(X(b.position[0]), Y(b.position[1]), 5, 0, 2 * Math.PI);
  g.fill();
  if (b.run === "Paused") {
    // The pause point: where the bead stopped and will go on from (the board's status
    // field; the head itself may be parked elsewhere).
    const p = b.pause_point || b.position;
    g.strokeStyle = "#2471a3";
    g.lineWidth = 2;
    g.beginPath();
    g.arc(X(p[0]), Y(p[1]), 9, 0, 2 * Math.PI);
    g.stroke();
    g.fillStyle = "#2471a3";
    g.fillText("pause point", X(p[0]) + 12, Y(p[1]) - 8);
  }
}

function renderBoards(data) {
  if (!data) return;
  lastBoards = data;
  if (data.console_seq !== app.consoleSeq) {
    app.consoleSeq = data.console_seq;
    loadConsole();
  }
  renderHeader(data);
  // A print that ended: the history has a new record.
  for (const b of data.boards) {
    const ended = /^(finished|aborted|halted)/.test(b.activity);
    if (ended && lastActivity[b.id] !== b.activity) setTimeout(loadHistory, 300);
    lastActivity[b.id] = b.activity;
  }
  const box = $("boards");
  for (const b of data.boards) {
    let card = box.querySelector(`.board[data-board="${b.id}"]`);
    if (!card) box.append((card = boardCard(b)));
    const q = (s) => card.querySelector(s);
    q(".state").textContent = b.connected ? b.activity : "not connected";
    // Each control acts only where the board can (the server's rule, the reason on hover).
    for (const button of card.querySelectorAll("button[data-action]")) {
      const action = button.dataset.action;
      const why = action === "send" ? (app.job ? null : "slice a design first (Design page)") : (b.refused || {})[action];
      button.disabled = !!why;
      button.title = why || "";
    }
    card.dataset.activity = b.activity;
    card.dataset.run = b.run;
    card.dataset.progress = String(b.progress);
    card.dataset.seq = String(b.seq);
    card.dataset.elapsed = String(b.elapsed_s);
    card.dataset.eta = b.eta_s == null ? "" : String(b.eta_s);
    q(".seq").textContent = `(${b.mode}, update ${b.seq})`;
    const ctl = data.controllers[b.id];
    const other = ctl && ctl !== TAB;
    q(".take").hidden = !other;
    q(".fault").hidden = !b.fault;
    q(".fault").textContent = b.fault || "";
    q(".board-msg").textContent = other ? "Another tab commands this board; its status is shown here." : (b.message || "");
    q(".job-line").textContent = b.job ? `Job: ${b.job.name} (${b.command} of ${b.commands} commands, layer ${b.layer})` : "No job sent yet.";
    q(".print-progress").value = b.progress;
    const valves = [0, 1, 2, 3].map((i) => ((b.valves >> i) & 1 ? "●" : "○")).join("");
    const finish = b.finish_unix_ms && b.eta_s > 0 ? `  finishes at ${new Date(b.finish_unix_ms).toLocaleTimeString([], { hour: "2-digit", minute: "2-digit" })}` : "";
    q(".live").textContent = `${(b.progress * 100).toFixed(1)} %  ETA ${fmtTime(b.eta_s)}${finish}  elapsed ${fmtTime(b.elapsed_s)}\n` +
      `x ${b.position[0].toFixed(2)} y ${b.position[1].toFixed(2)} z ${b.position[2].toFixed(2)} mm  valves ${valves}  ${b.speed.toFixed(1)} mm/s  ${b.homed ? "homed" : "not homed"}\n` +
      (b.flow_source === "plant"
        ? `flow ${b.flow.toFixed(2)} mm³/s (reference plant; the board's model says ${b.flow_model.toFixed(2)})  lines ${b.line_kpa.map((p) => p.toFixed(1)).join(" / ")} kPa`
        : `flow ${b.flow.toFixed(2)} mm³/s (the board's model)`) +
      (b.pause_latency_ms
        ? `\npause: valves shut ${fmtMs(b.pause_latency_ms[0])}, head at rest ${fmtMs(b.pause_latency_ms[1])} after the request (as polled)`
        : "");
    q(".upload-row").hidden = !b.upload;
    if (b.upload) {
      q(".upload-progress").value = b.upload[0] / Math.max(b.upload[1], 1);
      q(".upload-text").textContent = ` ${b.upload[0]} of ${b.upload[1]} bytes`;
    }
    // Rebuilt only when the queue changes: a row under the pointer stays the same element
    // through the ten updates a second (a held click lands on it).
    const queueKey = b.queue.map((j) => j.job).join(",");
    if (q(".queue").dataset.key !== queueKey) {
      q(".queue").dataset.key = queueKey;
      q(".queue").replaceChildren(b.queue.length ? "Queue: " : "", ...b.queue.map((j) => el("span", { class: "queued", "data-job": String(j.job) }, `${j.name} (job ${j.job}) `, el("button", { class: "unqueue", onclick: () => boardAction(b.id, "unqueue", { job: j.job }) }, "remove"), " ")));
    }
    if (!$("page-print").hidden) drawBoard(b.id);
    addTrend(b.id, (data.trend || [])[b.id]);
  }
}

// The header, on every page: each board's state and its print's progress, with its Abort
// (the emergency stop is never a page away). Rebuilt only when the boards or which of
// them are connected change; the text is updated in place.
function renderHeader(data) {
  const box = $("header-boards");
  const key = data.boards.map((b) => `${b.id}:${b.connected}`).join(",");
  if (box.dataset.key !== key) {
    box.dataset.key = key;
    box.replaceChildren(...data.boards.map((b) => el("span", { class: "badge", "data-board": String(b.id) },
      el("span", { class: "badge-text" }),
      ...(b.connected ? [el("button", { class: "abort-now", onclick: () => boardAction(b.id, "abort") }, "Abort")] : []))));
  }
  for (const b of data.boards) {
    const badge = box.querySelector(`.badge[data-board="${b.id}"]`);
    if (!badge) continue;
    const state = b.connected ? b.activity.split(":")[0] : "not connected";
    const pct = b.job && (b.mode === "Job" || b.progress > 0) ? ` ${(b.progress * 100).toFixed(0)} %` : "";
    badge.querySelector(".badge-text").textContent = `${data.boards.length > 1 ? b.id + ": " : ""}${state}${pct}`;
    badge.dataset.state = b.fault ? "fault" : b.mode === "Job" ? "printing" : b.connected ? "idle" : "off";
    // A board with no config loaded cannot move or open a valve: nothing to stop. (Its
    // title is set here only, as the button is built just above when it is new.)
    const stop = badge.querySelector(".abort-now");
    if (stop) {
      stop.disabled = b.mode === "Unconfigured";
      stop.title = stop.disabled ? `${b.name} has no config loaded: nothing moves, nothing to stop` : `stop ${b.name} now (valves shut, motion stops)`;
    }
  }
}

// The print history (newest first) and its totals; kept across restarts with --data.
async function loadHistory() {
  let h;
  try { h = await api("/api/history"); } catch (_) { return; }
  const s = h.stats;
  if (s.prints) $("history-stats").textContent = `${s.prints} print${s.prints > 1 ? "s" : ""}: ${s.finished} finished, ${s.aborted} aborted, ${s.halted} halted; ${fmtTime(s.printing_s)} printing in all.`;
  const rows = h.records.slice(-20).reverse().map((r) => el("tr", { "data-outcome": r.outcome },
    el("td", {}, new Date(r.ended_unix_s * 1000).toLocaleString()), el("td", {}, r.board_name), el("td", {}, r.job),
    el("td", {}, r.outcome), el("td", {}, fmtTime(r.printing_s)), el("td", {}, `${r.command} of ${r.commands}`)));
  $("history").replaceChildren(...rows);
}
const lastActivity = {};

function followBoards() {
  const es = new EventSource(`/api/boards/events?tab=${encodeURIComponent(TAB)}`);
  es.addEventListener("boards", (e) => renderBoards(JSON.parse(e.data)));
  es.onerror = () => {
    // The browser reconnects by itself; say so while it does.
    for (const m of document.querySelectorAll(".board-msg")) m.textContent = "Lost the dashboard server; reconnecting…";
  };
}

// ---------------------------------------------------------------- calibrate
let calFragment = null;
let calFrames = [];  // File objects chosen as camera frames, in file-name order
$("cal-file").addEventListener("change", (e) => {
  $("cal-name").textContent = e.target.files[0] ? e.target.files[0].name : "";
  if (e.target.files[0]) $("cal-sample").value = "";
});
// The bundled samples for the chosen fit; choosing one fills in what it needs.
function listSamples() {
  const what = $("cal-what").value;
  const list = (app.info && app.info.samples) || [];
  $("cal-sample").replaceChildren(el("option", { value: "" }, "none"),
    ...list.map((s, i) => [s, i]).filter(([s]) => s.what === what).map(([s, i]) => el("option", { value: String(i) }, s.name)));
}
$("cal-sample").addEventListener("change", () => {
  const i = $("cal-sample").value;
  if (i === "") return;
  const s = app.info.samples[Number(i)];
  $("cal-file").value = "";
  $("cal-name").textContent = s.name;
  if (s.what === "flow" && s.with) $("cal-density").value = s.with;
  if (s.what === "lag" && s.with) $("cal-lag-inlet").value = s.with;
});
function calWhatChanged() {
  const what = $("cal-what").value;
  for (const e of document.querySelectorAll("#page-calibrate [data-for]")) e.hidden = !e.dataset.for.split(" ").includes(what);
  $("cal-name").hidden = what === "camera";
  listSamples();
}
$("cal-what").addEventListener("change", calWhatChanged);
// The server takes the frames in file-name order: list them so.
function setFrames(list) {
  calFrames = Array.from(list).sort((a, b) => (a.name < b.name ? -1 : a.name > b.name ? 1 : 0));
  const bytes = calFrames.reduce((s, f) => s + f.size, 0);
  const names = calFrames.length > 4 ? [calFrames[0].name, "…", calFrames[calFrames.length - 1].name] : calFrames.map((f) => f.name);
  $("cal-frames-list").textContent = calFrames.length ? `${calFrames.length} frame${calFrames.length > 1 ? "s" : ""} (${(bytes / 1048576).toFixed(2)} MiB): ${names.join(" ")}` : "";
}
$("cal-frames").addEventListener("change", (e) => setFrames(e.target.files));
dropZone($("cal-drop"), (files) => {
  $("cal-what").value = "camera";
  calWhatChanged();
  setFrames(files);
});
// The camera's fields, by the name the server reads them under.
const CAM_FIELDS = ["fps", "mm_per_px", "target_width", "nozzle", "roi", "window"];
function cameraForm(form) {
  if (!calFrames.length) throw new Error("Choose the frames first (or drop them on the page): two or more side views of the filament.");
  // Said here before sending what the server would refuse after the upload.
  const mb = app.info ? app.info.max_upload_mb : 64;
  const bytes = calFrames.reduce((s, f) => s + f.size, 0);
  if (bytes > mb * 1048576) throw new Error(`The frames are ${(bytes / 1048576).toFixed(1)} MiB together, over the ${mb} MiB one upload takes: send fewer frames, or crop them to the filament.`);
  const max = app.info ? app.info.camera_max_frames : 2000;
  if (calFrames.length > max) throw new Error(`${calFrames.length} frames: the dashboard fits at most ${max} at a time; send fewer (every other frame halves them: give half the fps then).`);
  for (const f of calFrames) form.append("frames", f, f.name);
  for (const k of CAM_FIELDS) form.append(k, $("cam-" + k).value);
}
$("cal-run").addEventListener("click", async () => {
  showError("cal-error", "");
  const what = $("cal-what").value;
  const form = new FormData();
  if (what === "camera") {
    try { cameraForm(form); } catch (e) { return showError("cal-error", e.message); }
  } else {
    let f = $("cal-file").files[0];
    const sample = $("cal-sample").value;
    if (!f && sample !== "") {
      // A bundled sample, fetched as the file a user would have chosen.
      const s = app.info.samples[Number(sample)];
      const r = await fetch(`/api/samples/${sample}`);
      if (!r.ok) return showError("cal-error", `the sample ${s.name} did not load`);
      f = new File([await r.blob()], s.name, { type: "text/csv" });
    }
    if (!f) return showError("cal-error", "Choose a measurement CSV (or a bundled sample) first.");
    form.append("data", f, f.name);
    form.append("kind", $("cal-kind").value);
    form.append("inlet", $("cal-lag-inlet").value);
    form.append("density", $("cal-density").value);
  }
  // Flow is fitted in the channel of the Design page's config (for the fragment); the
  // camera takes its nozzle bore and print-speed cap.
  if ((what === "flow" || what === "camera") && app.config) form.append("config", app.config.text);
  const run = $("cal-run");
  run.disabled = true;
  try {
    const r = await api(`/api/calibrate/${what}`, { method: "POST", body: form });
    $("cal-report").textContent = r.report;
    calFragment = r.fragment;
    $("cal-fragment").textContent = r.fragment || (what === "camera" ? "(no fragment: give the target line width for the head speed to write)" : "(no fragment: see the verdicts)");
    $("cal-plot").src = "data:image/png;base64," + r.plot_png_base64;
    $("cal-plot").hidden = false;
    $("cal-plot-none").hidden = true;
  } catch (e) {
    showError("cal-error", e.message);
    markField(e);
  } finally {
    run.disabled = false;
  }
});
// The fragment's `key = value` lines become edits in the config editor: keys before any
// table go to the chosen inlet; a fragment of several [[inlet]] tables (flow: one per
// material) fills that inlet and the next ones; keys under [motion] (camera: the print
// speed) are that table's.
$("cal-apply").addEventListener("click", async () => {
  if (!calFragment || !app.config) return showError("cal-error", "Fit a measurement first.");
  const first = Number($("cal-inlet").value);
  let inlet = first - 1;
  const edits = [];
  const tables = calFragment.split("\n").some((l) => l.trim() === "[[inlet]]");
  if (!tables) inlet = first;
  let table = null;
  for (const l of calFragment.split("\n")) {
    const t = l.trim();
    if (t === "[[inlet]]") { inlet += 1; table = null; continue; }
    const header = t.match(/^\[([a-z_]+)\]$/);
    if (header) { table = header[1]; continue; }
    if (!t.includes("=") || t.startsWith("#")) continue;
    const i = t.indexOf("=");
    const key = t.slice(0, i).trim();
    edits.push({ path: table ? `${table}.${key}` : `inlet[${inlet}].${key}`, raw: t.slice(i + 1).trim() });
  }
  if (!edits.length) return showError("cal-error", "This fragment has nothing to apply (see its comments).");
  try {
    const c = await postJson("/api/config/check", { text: app.config.text, edits });
    renderConfig(c);
    clearFieldErrors();
    // A config saved by name is written back: the calibration outlives a reload.
    const chosen = $("config-select").value;
    if (chosen.startsWith("saved:")) {
      await saveConfig(chosen.slice(6), c.text);
      toast(`Applied and saved to ${chosen.slice(6)}.`);
      return;
    }
    const onInlets = edits.filter((e) => e.path.startsWith("inlet[")).length;
    toast(!onInlets ? `Applied ${edits.map((e) => `${e.path} = ${e.raw}`).join(", ")}; the config on the Design page now uses it.`
      : inlet > first ? `Applied to inlets ${first} to ${inlet}; the config on the Design page now uses them.` : `Applied to inlet ${first}; the config on the Design page now uses it.`);
  } catch (e) {
    showError("cal-error", e.message);
    markField(e);
  }
});

// ---------------------------------------------------------------- start
(async function start() {
  try {
    app.info = await api("/api/info");
  } catch (e) {
    return toast(e.message, true);
  }
  for (const e of document.querySelectorAll(".max-upload")) e.textContent = app.info.max_upload_mb;
  $("cam-max-frames").textContent = app.info.camera_max_frames;
  $("cam-max-pixels").textContent = app.info.camera_max_pixels / 1e6;
  listSamples();
  loadHistory();
  const sel = $("config-select");
  app.info.configs.forEach((n, i) => sel.append(el("option", { value: String(i) }, n)));
  const bundled = $("bundled");
  const groups = [["logo.png"], ["chessboard.png"], ["cube-shell.stl", "cube-ball.stl"]];
  for (const g of groups) {
    bundled.append(el("button", { class: "bundled", "data-design": g[0], onclick: () => useBundled(g) }, g.join(" + ")), " ");
  }
  await listSavedConfigs();
  // What this browser was doing: the config it chose, the design it sliced last.
  const chosen = localStorage.getItem("dollop-config");
  const known = chosen && Array.from(sel.options).some((o) => o.value === chosen);
  if (known) sel.value = chosen;
  await loadConfig(known ? chosen : 0);
  let restored = false;
  let last = null;
  try {
    last = JSON.parse(localStorage.getItem("dollop-design") || "null");
    if (last && last.kept) {
      for (const [k, v] of Object.entries(last.options || {})) {
        const input = $("opt-" + k);
        if (!input) continue;
        if (input.type === "checkbox") input.checked = !!v; else input.value = v;
      }
      setJob(await postJson(`/api/store/${encodeURIComponent(last.kept)}/open`, { config: app.config ? app.config.text : null, options: last.options }));
      restored = true;
    }
  } catch (e) {
    // Say so rather than open another job in its place unannounced (the file was deleted,
    // or the config it was sliced with no longer checks).
    if (last && last.kept) toast(`Your last job, ${last.kept}, could not be reopened: ${e.message}`, true);
    localStorage.removeItem("dollop-design");
  }
  if (app.info.demo_job && !restored) {
    try {
      setJob(await api(`/api/jobs/${app.info.demo_job}`));
    } catch (e) { toast(e.message, true); }
  }
  showCamera(app.info.camera);
  $("files-board").replaceChildren(...Array.from({ length: app.info.boards }, (_, i) => el("option", { value: String(i) }, String(i))));
  followBoards();
})();

// ---------------------------------------------------------------- live plots
// A board's trend (one sample a second, the last minutes): fetched once, then the newest
// sample of each status update is added.
async function loadTrend(id) {
  try {
    const r = await api(`/api/boards/${id}/trend`);
    const have = app.trend[id] || [];
    const last = r.samples.length ? r.samples[r.samples.length - 1].unix_ms : 0;
    app.trend[id] = r.samples.concat(have.filter((s) => s.unix_ms > last));
  } catch (_) { app.trend[id] = app.trend[id] || []; }
  drawTrend(id);
}
function addTrend(id, s) {
  if (!s) return;
  const t = app.trend[id] || (app.trend[id] = []);
  if (t.length && t[t.length - 1].unix_ms >= s.unix_ms) return;
  t.push(s);
  while (t.length > 300) t.shift();
  if (!$("page-print").hidden) drawTrend(id);
}
function drawTrend(id) {
  const card = document.querySelector(`.board[data-board="${id}"]`);
  const t = app.trend[id];
  if (!card || !t) return;
  const now = t.length ? t[t.length - 1].unix_ms : Date.now();
  const series = {
    t: t.map((s) => (s.unix_ms - now) / 1000),
    speed: t.map((s) => s.speed),
    flow: t.map((s) => s.flow),
  };
  const inlets = t.reduce((n, s) => Math.max(n, s.line_kpa.length), 0);
  const src = { series, t0: Math.min(-60, series.t.length ? series.t[0] : -60), t1: 0 };
  for (const c of card.querySelectorAll("canvas.trend-plot")) {
    // Drawn at the size it is shown: labels stay 12 px on a phone.
    const w = Math.max(240, Math.round(c.clientWidth || 600));
    if (c.width !== w) c.width = w;
    const k = c.dataset.trend;
    if (k === "speed") drawPlot(c, "head speed", "mm/s", [{ y: series.speed, colour: "#2f6f5e" }], undefined, src);
    else if (k === "flow") drawPlot(c, "flow", "mm³/s", [{ y: series.flow, colour: "#3a7bd5" }], undefined, src);
    else drawPlot(c, "line pressure", "kPa", Array.from({ length: inlets }, (_, i) => ({ y: t.map((s) => s.line_kpa[i]), colour: COLOURS[i % 8], name: String(i) })), undefined, src);
  }
}

// ---------------------------------------------------------------- console
async function loadConsole() {
  let r;
  try { r = await api("/api/console"); } catch (_) { return; }
  const lines = r.lines.slice(0, 100);
  $("console").replaceChildren(...lines.map((l) => el("li", { class: l.level === "error" ? "bad" : "", "data-seq": String(l.seq) },
    el("span", { class: "muted" }, new Date(l.unix_ms).toLocaleTimeString() + " "), el("b", {}, l.source + ": "), l.text)));
  $("console-last").textContent = lines.length ? `${lines[0].source}: ${lines[0].text}` : "";
  if (!$("page-files").hidden && lines.some((l) => /kept|deleted|upload/.test(l.text))) loadFiles();
}

// ---------------------------------------------------------------- files
function fmtBytes(n) {
  return n < 1024 ? `${n} B` : n < 1048576 ? `${(n / 1024).toFixed(1)} KiB` : `${(n / 1048576).toFixed(1)} MiB`;
}
async function loadFiles() {
  let r;
  try { r = await api("/api/store"); } catch (e) { return showError("files-error", e.message); }
  $("files-max").textContent = r.max_files;
  $("files-none").hidden = r.files.length > 0;
  const rows = r.files.map((f) => {
    const enc = encodeURIComponent(f.name);
    return el("tr", { "data-file": f.name, "data-kind": f.kind },
      el("td", { class: "file-name" }, f.name), el("td", {}, f.kind), el("td", {}, fmtBytes(f.bytes)),
      el("td", {}, new Date(f.modified_unix_s * 1000).toLocaleString()),
      el("td", { class: "file-actions" },
        el("a", { href: `/api/store/${enc}`, download: f.name }, "download"), " ",
        el("button", { class: "file-open", title: f.kind === "job" ? "show it on the Design page" : "slice it again with the Design page's config and options", onclick: () => openFile(f.name) }, f.kind === "job" ? "Open" : "Re-slice"), " ",
        el("button", { class: "file-print", onclick: () => printFile(f.name) }, "Print"), " ",
        el("button", { class: "file-delete", onclick: () => deleteFile(f.name) }, "Delete")));
  });
  $("files").replaceChildren(...(rows.length ? [el("tr", {}, ...["name", "kind", "size", "date", ""].map((h) => el("th", {}, h)))] : []), ...rows);
}
async function fileJob(name) {
  return postJson(`/api/store/${encodeURIComponent(name)}/open`, { config: app.config ? app.config.text : null, options: sliceOptions() });
}
async function openFile(name) {
  showError("files-error", "");
  try {
    setJob(await fileJob(name));
    if (/\.dlp$/i.test(name)) localStorage.setItem("dollop-design", JSON.stringify({ kept: name, options: sliceOptions() }));
    showPage("design");
  } catch (e) { showError("files-error", e.message); }
}
async function printFile(name) {
  showError("files-error", "");
  try {
    const job = await fileJob(name);
    app.jobs[job.id] = job;
    await boardAction(Number($("files-board").value || 0), "send", { job: job.id });
  } catch (e) { showError("files-error", e.message); }
}
async function deleteFile(name) {
  if (!confirm(`Delete ${name} from the data folder?`)) return;
  try {
    await api(`/api/store/${encodeURIComponent(name)}`, { method: "DELETE" });
    toast(`Deleted ${name}.`);
  } catch (e) { toast(e.message, true); }
  loadFiles();
}
$("files-upload").addEventListener("change", async (e) => {
  const f = e.target.files[0];
  if (!f) return;
  showError("files-error", "");
  const form = new FormData();
  form.append("file", f, f.name);
  if (app.config) form.append("config", app.config.text);
  try {
    const r = await upload("/api/store", form, $("files-progress"));
    toast(`Kept ${r.name}.`);
  } catch (err) { showError("files-error", err.message); }
  e.target.value = "";
  loadFiles();
});

// ---------------------------------------------------------------- camera
// `dollop serve --camera URL`: an MJPEG stream plays as it comes; a snapshot URL is
// fetched again every two seconds while the Print page is shown.
function showCamera(url) {
  if (!url) return;
  $("camera-panel").hidden = false;
  const img = $("camera-img");
  const stream = /mjpe?g|stream/i.test(url);
  img.onerror = () => { $("camera-note").textContent = `The camera at ${url} does not answer.`; };
  img.onload = () => { $("camera-note").textContent = stream ? `Live from ${url}` : `Snapshot from ${url}, ${new Date().toLocaleTimeString()}`; };
  img.src = url;
  $("camera-inspect").onclick = inspectFromCamera;
  if (!stream) setInterval(() => {
    if ($("page-print").hidden) return;
    img.src = url + (url.includes("?") ? "&" : "?") + "t=" + Date.now();
  }, 2000);
}

// "Inspect this print": the server takes a picture from the camera and measures it against
// the current job (`dollop inspect --suggest`); the report, the fragment and the picture.
async function inspectFromCamera() {
  const err = $("camera-inspect-error");
  err.hidden = true;
  if (!app.job) { err.textContent = "Slice or open the job this print was made from first (Design or Files page)."; err.hidden = false; return; }
  const btn = $("camera-inspect");
  btn.disabled = true;
  btn.textContent = "Measuring...";
  try {
    const r = await postJson("/api/inspect", { job: app.job.id });
    $("camera-inspect-img").src = r.picture;
    $("camera-inspect-report").textContent = r.report + (r.suggestions.length ? "suggestions:\n  " + r.suggestions.join("\n  ") + "\n" : "");
    $("camera-inspect-fragment").textContent = r.fragment ? "Config fragment (apply with dollop config --apply, or paste it on the Design page):\n" + r.fragment : (r.no_correction_needed ? "No correction needed: the config already puts the boundaries where the picture shows them." : "");
    $("camera-inspection").hidden = false;
  } catch (e) {
    err.textContent = e.message;
    err.hidden = false;
  } finally {
    btn.disabled = false;
    btn.textContent = "Inspect this print";
  }
}
