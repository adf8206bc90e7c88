// posicast designer: sends each form to the server's JSON API and shows the answer.
// All computation is on the server (posicast); this script only reads fields and draws tables.
"use strict";

const $ = (id) => document.getElementById(id);
const val = (id) => $(id).value.trim();

function fmt(x, digits = 6) {
  if (x === null || x === undefined) return "–";
  if (typeof x !== "number") return String(x);
  if (x === 0) return "0";
  const a = Math.abs(x);
  if (a >= 1e-3 && a < 1e6) return String(Number(x.toPrecision(digits)));
  return x.toExponential(digits - 1);
}
const pct = (x) => (x === null || x === undefined ? "–" : Math.abs(x) < 5e-6 ? "0 %" :
  Math.abs(x) < 0.01 ? (100 * x).toPrecision(2) + " %" : (100 * x).toFixed(1) + " %");

function table(head, rows, cls = "") {
  const h = "<tr>" + head.map((c) => `<th>${c}</th>`).join("") + "</tr>";
  const b = rows.map((r) => `<tr class="${r.cls || ""}">` +
    r.cells.map((c) => `<td>${c}</td>`).join("") + "</tr>").join("");
  return `<table class="${cls}"><thead>${h}</thead><tbody>${b}</tbody></table>`;
}

function esc(s) {
  return String(s).replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" }[c]));
}

// ---- status line: working..., or the library's one-line message ----
function status(tab, text, kind = "") {
  const el = $(tab + "-status");
  el.textContent = text;
  el.className = "status " + kind;
}

const seq = {};  // per tab: the latest request wins (sliders send many)

async function post(tab, path, body, { download = false } = {}) {
  const n = (seq[tab] = (seq[tab] || 0) + 1);
  status(tab, "working…", "working");
  document.body.classList.add("busy-" + tab);
  const t0 = performance.now();
  let resp;
  try {
    resp = await fetch(path, { method: "POST", headers: { "Content-Type": "application/json" },
      body: JSON.stringify(body) });
  } catch (e) {
    if (n === seq[tab]) { status(tab, "the server did not answer: " + e, "error"); }
    document.body.classList.remove("busy-" + tab);
    return null;
  }
  if (n !== seq[tab]) return null;  // a newer request is on its way
  document.body.classList.remove("busy-" + tab);
  if (!resp.ok) {
    let msg = "HTTP " + resp.status;
    try { msg = (await resp.json()).error || msg; } catch (e) { /* not JSON */ }
    status(tab, msg, "error");
    if (!download) clearResults(tab);  // never the last answer beside an error about new input
    return null;
  }
  status(tab, `done in ${((performance.now() - t0) / 1000).toFixed(1)} s`, "ok");
  return download ? resp : resp.json();
}

// The results a tab shows; emptied when a request fails, so that an old answer (config lines to copy, a
// "stable" verdict) is never left beside the error about the new input.  The design tab keeps its last
// design while a slider or a number is being edited (its status line says what is wrong).
const RESULTS = {
  m: ["m-modes-table", "m-candidates", "m-notes", "m-psd", "m-cand-plot"],
  l: ["l-verdict", "l-poles", "l-metrics", "l-spectrum", "l-step", "l-load"],
};
function clearResults(tab) {
  for (const id of RESULTS[tab] || []) $(id).innerHTML = "";
  if (tab === "m") $("m-config").value = "";
  if (tab === "l") $("l-verdict").className = "verdict";
}

// ---- tabs ----
function showTab(name) {
  document.querySelectorAll(".tab").forEach((b) => b.classList.toggle("active", b.dataset.tab === name));
  document.querySelectorAll(".panel").forEach((p) => p.classList.toggle("active", p.id === name));
  if (location.hash !== "#" + name) history.replaceState(null, "", "#" + name);
}

// ================================ machine ================================
function machineFields() {
  return { firmware: val("m-firmware"), axis: val("m-axis"), margin: val("m-margin"), vtol: val("m-vtol"),
    input: val("m-input"), output: val("m-output") };
}

let lastFiles = null;

async function machineRun(body) {
  const r = await post("m", "/api/machine", body);
  if (!r) return;
  $("m-config").value = r.config;
  let modesHtml = "";
  for (const f of r.files) {
    modesHtml += `<p class="muted">${esc(f.name)}, axis ${esc(f.axis || "?")}` +
      (f.no_mode ? `: no resonance (${esc(f.no_mode)})` : "") + "</p>";
    if (!f.modes.length) continue;
    modesHtml += table(["frequency [Hz]", "95 % interval", "damping ζ", "95 % interval", "share"],
      f.modes.map((m) => ({ cells: [fmt(m.freq_hz, 4),
        m.freq_hz_95 ? `${fmt(m.freq_hz_95[0], 4)} – ${fmt(m.freq_hz_95[1], 4)}` : "typed",
        fmt(m.zeta, 3), m.zeta_95 ? `${fmt(m.zeta_95[0], 3)} – ${fmt(m.zeta_95[1], 3)}` : "typed",
        m.share === null ? "–" : fmt(m.share, 2)] })), "num");
  }
  $("m-modes-table").innerHTML = modesHtml;
  let html = "";
  const notes = [...r.notes];
  for (const rec of r.recommendations) {
    html += `<h3>${esc(rec.firmware)}${rec.axis ? ", axis " + esc(rec.axis) : ""}: recommended ${esc(rec.best)}</h3>`;
    html += table(["shaper", "frequency [Hz]", "design ζ", "worst-case vibration", "firmware's measure",
      "smoothing [mm]", "max_accel [mm/s²]", ""],
      rec.candidates.map((c) => ({ cls: c.recommended ? "best" : "", cells: [esc(c.type), fmt(c.freq_hz, 4),
        fmt(c.damping, 3), pct(c.vibration), pct(c.firmware_vibration), fmt(c.smoothing_mm, 3),
        c.max_accel === null ? "–" : Math.round(c.max_accel).toString(),
        (c.recommended ? "recommended" : "") + (c.own_tool ? (c.recommended ? ", " : "") + "firmware tool's pick" : "")] })),
      "num");
    notes.push(...rec.reasoning);
  }
  $("m-candidates").innerHTML = html;
  $("m-notes").innerHTML = notes.map((n) => `<li>${esc(n)}</li>`).join("");
  $("m-psd").innerHTML = r.plots.psd || "<p class='muted'>No measured spectrum (modes typed by hand, or an " +
    "input/output record fitted in time).</p>";
  $("m-cand-plot").innerHTML = r.plots.candidates || "";
}

function readText(file) {
  return new Promise((resolve, reject) => {
    const reader = new FileReader();
    reader.onload = () => resolve({ name: file.name, text: reader.result });
    reader.onerror = () => reject(new Error("could not read " + file.name));
    reader.readAsText(file);
  });
}

async function machineFiles(fileList) {
  const files = [...fileList];
  status("m", `reading ${files.map((f) => f.name).join(", ")}…`, "working");
  try { lastFiles = await Promise.all(files.map(readText)); }
  catch (e) { status("m", e.message, "error"); return; }
  machineRun({ ...machineFields(), files: lastFiles });
}

function machineInit() {
  $("m-file").addEventListener("change", (e) => {
    if (e.target.files.length) machineFiles(e.target.files);
  });
  const drop = $("m-drop");
  drop.addEventListener("dragover", (e) => { e.preventDefault(); drop.classList.add("over"); });
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  drop.addEventListener("drop", (e) => {
    e.preventDefault(); drop.classList.remove("over");
    if (e.dataTransfer.files.length) machineFiles(e.dataTransfer.files);
  });
  $("m-run-modes").addEventListener("click", () => { lastFiles = null; machineRun({ ...machineFields(), modes: $("m-modes").value }); });
  for (const id of ["m-firmware", "m-axis", "m-margin", "m-vtol", "m-input", "m-output"]) {
    $(id).addEventListener("change", () => {
      if (lastFiles) machineRun({ ...machineFields(), files: lastFiles });
      else if ($("m-config").value && $("m-modes").value.trim()) machineRun({ ...machineFields(), modes: $("m-modes").value });
    });
  }
  $("m-copy").addEventListener("click", async () => {
    $("m-config").select();
    try { await navigator.clipboard.writeText($("m-config").value); status("m", "copied", "ok"); }
    catch (e) { document.execCommand("copy"); }
  });
}

// ================================ design ================================
let KINDS = [];

function designBody() {
  const modes = [{ freq_hz: val("d-freq-num"), zeta: val("d-zeta-num") }];
  if ($("d-mode2").checked) modes.push({ freq_hz: val("d-freq2-num"), zeta: val("d-zeta2-num") });
  const params = {};
  document.querySelectorAll("#d-params input").forEach((el) => { params[el.name] = el.value.trim(); });
  return { kind: val("d-kind"), modes, params, vtol: val("d-vtol"), sample_rate: val("d-fs") };
}

async function designRun() {
  const r = await post("d", "/api/design", designBody());
  if (!r) return;
  $("d-summary").textContent = `${r.name}: ${r.n_impulses} impulse${r.n_impulses === 1 ? "" : "s"}, ` +
    (r.duration === null ? "duration ∞" : `duration ${fmt(1000 * r.duration, 5)} ms`) +
    (r.note ? ` (${r.note})` : "");
  $("d-impulses").innerHTML = table(["#", "time [s]", "amplitude"],
    r.impulses.map((p, i) => ({ cells: [String(i + 1), fmt(p[0], 6), fmt(p[1], 6)] })), "num") +
    (r.more ? `<p class="muted">… ${r.more} more</p>` : "");
  $("d-ins").innerHTML = table(["mode", "residual at the mode", `band with V ≤ ${fmt(100 * r.insensitivity[0].vtol, 3)} %`, "width I"],
    r.insensitivity.map((b) => ({ cells: [`${fmt(b.freq_hz, 4)} Hz, ζ ${fmt(b.zeta, 3)}`, pct(b.residual),
      b.width > 0 ? `${fmt(b.low * b.freq_hz, 4)} – ${fmt(b.high * b.freq_hz, 4)} Hz` +
        (b.at_limit ? " (the search range's end: the band goes on)" : "") : "none",
      (b.at_limit ? "≥ " : "") + fmt(b.width, 4)] })), "num");
  if (r.taps) {
    const t = r.taps;
    $("d-taps-method").textContent = `${t.n_taps} tap${t.n_taps === 1 ? "" : "s"} at ${fmt(t.sample_rate)} Hz: ${t.method}; sum ${fmt(t.sum, 6)}` +
      (t.residual_vibration.length ? "; residual at the mode(s) " + t.residual_vibration.map(pct).join(", ") : "") +
      (t.iir ? "; plus an IIR section (in the export)" : "");
    $("d-taps").innerHTML = table(["sample", "time [s]", "weight"],
      t.rows.map((p) => ({ cells: [String(p[0]), fmt(p[1], 6), fmt(p[2], 6)] })), "num") +
      (t.more ? `<p class="muted">… ${t.more} more (all in the export)</p>` : "");
  } else {
    $("d-taps-method").textContent = "give a sample rate to see the taps";
    $("d-taps").innerHTML = "";
  }
  $("d-sens").innerHTML = r.plots.sensitivity;
  $("d-imp").innerHTML = r.plots.impulses;
}

let designTimer = null;
function designSoon() {  // debounced: a slider sends one request per pause, not one per pixel
  clearTimeout(designTimer);
  designTimer = setTimeout(designRun, 250);
}

function designParams() {
  const k = KINDS.find((x) => x.kind === val("d-kind"));
  $("d-kind-summary").textContent = k ? k.summary : "";
  const box = $("d-params");
  box.innerHTML = "";
  if (!k) return;
  for (const [name, def] of Object.entries(k.params)) {
    const shown = def === null ? "auto" : Array.isArray(def) ? def.join(" ") : String(def);
    const lab = document.createElement("label");
    lab.textContent = name + " ";
    const inp = document.createElement("input");
    inp.name = name; inp.value = shown; inp.size = 8; inp.id = "d-param-" + name;
    inp.addEventListener("input", designSoon);
    lab.appendChild(inp);
    box.appendChild(lab);
  }
}

function pairSlider(range, num) {
  $(range).addEventListener("input", () => { $(num).value = $(range).value; designSoon(); });
  $(num).addEventListener("input", () => {
    const x = parseFloat($(num).value);
    if (Number.isFinite(x)) $(range).value = x;
    designSoon();
  });
}

async function designExport() {
  const body = { ...designBody(), format: val("d-format"), form: val("d-layout"), name: val("d-name"),
    inverse: $("d-inverse").checked };
  const resp = await post("d", "/api/export", body, { download: true });
  if (!resp) return;
  const blob = await resp.blob();
  const cd = resp.headers.get("Content-Disposition") || "";
  const m = /filename="([^"]+)"/.exec(cd);
  const a = document.createElement("a");
  a.href = URL.createObjectURL(blob);
  a.download = m ? m[1] : "shaper.txt";
  document.body.appendChild(a); a.click(); a.remove();
  status("d", "exported " + a.download, "ok");
}

function designInit() {
  pairSlider("d-freq", "d-freq-num");
  pairSlider("d-zeta", "d-zeta-num");
  pairSlider("d-freq2", "d-freq2-num");
  pairSlider("d-zeta2", "d-zeta2-num");
  $("d-mode2").addEventListener("change", () => { $("d-mode2-fields").hidden = !$("d-mode2").checked; designSoon(); });
  $("d-kind").addEventListener("change", () => { designParams(); designSoon(); });
  for (const id of ["d-vtol", "d-fs"]) $(id).addEventListener("input", designSoon);
  $("d-export").addEventListener("click", designExport);
}

// ================================ loop ================================
function loopBody() {
  const b = { architecture: val("l-arch"), shaper: val("l-shaper"), freq_hz: val("l-freq"), zeta: val("l-zeta"),
    region: val("l-region"), t_end: val("l-tend") };
  for (const k of ["G", "C", "F"]) for (const p of ["num", "den", "delay"]) b[`${k}_${p}`] = val(`l-${k}-${p}`);
  return b;
}

async function loopRun() {
  const r = await post("l", "/api/loop", loopBody());
  if (!r) return;
  const v = r.verdict;
  const word = v.stable ? "stable" : v.marginal ? "marginally stable (not exponentially stable)" : "unstable";
  $("l-verdict").className = "verdict " + (v.stable ? "stable" : "unstable");
  $("l-verdict").innerHTML = `<strong id="l-verdict-word">${word}</strong> <span class="muted">(${esc(v.kind)} ` +
    `characteristic, certified)</span><br><span id="l-verdict-reason">${esc(v.reason)}</span>` +
    (v.unstable_roots.length ? `<br>roots with Re s ≥ 0: ${v.unstable_roots.map(esc).join(", ")}` : "");
  $("l-poles").innerHTML = `<p class="muted">${esc(r.loop)}; ${r.n_poles} poles in Re s ∈ [${fmt(r.region[0], 3)}, ` +
    `${fmt(r.region[1], 3)}], Im s ∈ [${fmt(r.region[2], 3)}, ${fmt(r.region[3], 3)}]</p>` +
    (r.poles.length ? `<p id="l-pole-list">${r.poles.map(esc).join(", &nbsp;")}</p>` : "");
  const m = r.metrics;
  $("l-metrics").innerHTML = r.responses_error ? `<p class="error">responses: ${esc(r.responses_error)}</p>` :
    `<p>simulated to ${fmt(m.t_end, 4)} s (${esc(m.mode)}): overshoot ${m.overshoot_percent === undefined ? "–" : fmt(m.overshoot_percent, 3) + " %"}, ` +
    `settling (2 %) ${m.settling_time === undefined || m.settling_time === null ? "–" : fmt(m.settling_time, 4) + " s"}, ` +
    `peak of y after a unit load step ${m.load_peak === undefined ? "–" : fmt(m.load_peak, 4)}` +
    (m.step_diverged ? `; step: ${esc(m.step_diverged)}` : "") + (m.load_diverged ? `; load: ${esc(m.load_diverged)}` : "") + "</p>";
  $("l-spectrum").innerHTML = r.plots.spectrum || "";
  $("l-step").innerHTML = r.plots.step || "";
  $("l-load").innerHTML = r.plots.load || "";
}

async function loopTune() {
  const body = { ...loopBody(), controller: val("l-controller"), ms: val("l-ms"),
    derivative_filter: val("l-controller") === "pd" ? val("l-tf") : "" };
  $("l-tune-out").textContent = "tuning… (a region search in the gain plane: a few seconds)";
  const r = await post("l", "/api/tune", body);
  if (!r) { $("l-tune-out").textContent = ""; return; }
  $("l-tune-out").textContent = r.summary + `\n(${r.seconds.toFixed(1)} s)`;
  if (r.C_num !== null) {
    $("l-C-num").value = r.C_num; $("l-C-den").value = r.C_den; $("l-C-delay").value = "0";
    await loopRun();
  }
}

function loopInit() {
  $("l-run").addEventListener("click", loopRun);
  $("l-tune").addEventListener("click", loopTune);
}

// ================================ start ================================
async function init() {
  document.querySelectorAll(".tab").forEach((b) => b.addEventListener("click", () => showTab(b.dataset.tab)));
  machineInit(); designInit(); loopInit();
  const info = await (await fetch("/api/kinds")).json();
  KINDS = info.kinds;
  $("version").textContent = "posicast " + info.version;
  $("d-kind").innerHTML = KINDS.map((k) => `<option value="${k.kind}">${k.kind}</option>`).join("");
  $("d-kind").value = "zvd";
  $("l-shaper").innerHTML = `<option value="none">none</option>` +
    KINDS.map((k) => `<option value="${k.kind}">${k.kind}</option>`).join("");
  $("l-shaper").value = "zvd";
  $("l-arch").innerHTML = info.architectures.map((a) => `<option>${a}</option>`).join("");
  $("l-arch").value = "control_action";
  designParams();
  const tab = location.hash.replace("#", "");
  if (["machine", "design", "loop"].includes(tab)) showTab(tab);
  document.body.dataset.ready = "1";
  designRun();
  loopRun();
}

document.addEventListener("DOMContentLoaded", init);
