// ipfn view: the plane as tiles (pan by dragging, zoom with the wheel), the controls, and a run's
// plots and previews. The URL's hash holds the view, so a view can be shared and reopened.
"use strict";
(function () {
  const $ = (id) => document.getElementById(id);
  const REPORT = window.IPFN_REPORT;
  const TILE = 256;
  const MAX_POSITION = 1000000;
  const MAX_IN_FLIGHT = 4; // tiles fetched at once: the browser keeps connections for the rest
  const state = { seed: "0", zoom: 1, noise: 1, tile: false, period: "256x256", guide: "x",
    frame: "1024x1024", density: 0.3, map: 0, axis: "z", depth: 0, cx: 0, cy: 0 };
  let info = null;
  const shown = new Map(); // tile key -> img
  const waiting = []; // imgs whose tile is not fetched yet; the newest is fetched first
  const blobs = new Map(); // tile URL -> object URL of its PNG (the most recent 512)
  const pending = new Set(); // tile URLs being fetched
  let inFlight = 0;

  function readHash() {
    const p = new URLSearchParams(location.hash.slice(1));
    for (const k of Object.keys(state)) {
      if (!p.has(k)) continue;
      const v = p.get(k);
      if (typeof state[k] === "number") { if (v !== "" && isFinite(Number(v))) state[k] = Number(v); }
      else if (typeof state[k] === "boolean") state[k] = v === "1";
      else if (k !== "seed" || /^\d{1,20}$/.test(v)) state[k] = v;
    }
  }
  function writeHash() {
    const p = new URLSearchParams();
    for (const [k, v] of Object.entries(state)) p.set(k, typeof v === "boolean" ? (v ? "1" : "0") : String(v));
    history.replaceState(null, "", "#" + p.toString());
  }

  // The view's query: what /tile and /export take.
  function viewQuery() {
    const p = new URLSearchParams();
    p.set("seed", state.seed);
    p.set("zoom", String(state.zoom));
    p.set("noise", String(state.noise));
    const m = info.model;
    if (state.tile && m.dims === 2) p.set("tile", state.period);
    if (m.guided) { p.set("guide", state.guide); p.set("frame", state.frame); }
    if (m.density) p.set("density", String(state.density));
    if (m.maps.length) p.set("map", String(state.map));
    if (m.dims === 3) { p.set("axis", state.axis); p.set("depth", String(state.depth)); }
    return p;
  }

  function viewBox() {
    const plane = $("plane");
    const w = plane.clientWidth, h = plane.clientHeight;
    return { w, h, left: Math.round(state.cx - w / 2), top: Math.round(state.cy - h / 2) };
  }

  // Places the tiles that cover the plane; keeps those already loaded.
  function draw() {
    if (!info || !info.model) return;
    const { w, h, left, top } = viewBox();
    let tw = TILE, th = TILE;
    const tiled = state.tile && info.model.dims === 2;
    if (tiled) [tw, th] = state.period.split("x").map(Number);
    if (!(tw >= 64 && th >= 64)) { $("message").textContent = "tile: give the period as WxH, 64 to 2048, e.g. 256x256"; return; }
    $("tiles").classList.toggle("outlined", tiled);
    const base = viewQuery();
    base.set("v", info.model.version);
    const want = new Set();
    for (let j = Math.floor(top / th); j * th < top + h; j++) {
      for (let i = Math.floor(left / tw); i * tw < left + w; i++) {
        const x = i * tw, y = j * th;
        if (!tiled && (Math.abs(x) > MAX_POSITION || Math.abs(y) > MAX_POSITION)) continue;
        const q = new URLSearchParams(base);
        if (!tiled) { q.set("x", String(x)); q.set("y", String(y)); q.set("size", String(TILE)); }
        const url = "/tile?" + q.toString();
        const key = i + "," + j + " " + url;
        want.add(key);
        let img = shown.get(key);
        if (!img) {
          img = document.createElement("img");
          img.dataset.x = String(x); img.dataset.y = String(y);
          img.dataset.url = url;
          img.dataset.tries = "0";
          $("tiles").appendChild(img);
          shown.set(key, img);
          if (blobs.has(url)) img.src = blobs.get(url); else waiting.push(img);
        }
        img.style.left = (x - left) + "px";
        img.style.top = (y - top) + "px";
      }
    }
    for (const [key, img] of shown) if (!want.has(key)) { drop(img); shown.delete(key); }
    pump();
  }

  // Fetches waiting tiles, newest first, at most MAX_IN_FLIGHT at once.
  function pump() {
    while (inFlight < MAX_IN_FLIGHT && waiting.length) {
      const img = waiting.pop();
      if (img.isConnected && !img.src) fetchTile(img);
    }
  }

  function fetchTile(img) {
    const url = img.dataset.url;
    if (blobs.has(url)) { img.src = blobs.get(url); return; }
    if (pending.has(url)) return; // tile mode: one fetch fills every copy of the tile
    pending.add(url);
    const abort = new AbortController();
    img.abort = abort;
    inFlight++;
    fetch(url, { signal: abort.signal }).then(async (r) => {
      if (r.ok) {
        const blob = URL.createObjectURL(await r.blob());
        blobs.set(url, blob);
        if (blobs.size > 512) blobs.delete(blobs.keys().next().value);
        for (const other of shown.values()) if (other.dataset.url === url && !other.src) other.src = blob;
        return;
      }
      const message = await r.text();
      if (r.status !== 503) { $("message").textContent = message; return; }
      // The server was busy: ask again a little later.
      const tries = Number(img.dataset.tries) + 1;
      img.dataset.tries = String(tries);
      if (tries <= 8) setTimeout(() => { if (img.isConnected) { waiting.push(img); pump(); } }, 250 * tries);
    }).catch(() => {}).finally(() => {
      inFlight--; pending.delete(url); img.abort = null;
      // Cancelled or failed: the tile's other copies still on screen fetch it themselves.
      if (!blobs.has(url)) {
        for (const other of shown.values()) if (other !== img && other.dataset.url === url && !other.src) waiting.push(other);
      }
      pump();
    });
  }

  // A tile that left the screen: its fetch is cancelled, so the server skips painting it.
  function drop(img) {
    if (img.abort) img.abort.abort();
    img.remove();
  }

  function redraw() {
    for (const img of shown.values()) drop(img);
    shown.clear();
    $("message").textContent = "";
    writeHash();
    draw();
  }

  function bindControls() {
    const fields = { seed: "seed", zoom: "zoom", noise: "noise", period: "period", guide: "guide",
      frame: "frame", density: "density", map: "map", axis: "axis", depth: "depth" };
    for (const [id, key] of Object.entries(fields)) {
      const el = $(id);
      el.value = String(state[key]);
      el.addEventListener("change", () => {
        state[key] = typeof state[key] === "number" ? Number(el.value) : el.value;
        redraw();
      });
    }
    $("tile").checked = state.tile;
    $("tile").addEventListener("change", () => { state.tile = $("tile").checked; redraw(); });
    $("new-seed").addEventListener("click", () => {
      state.seed = String(Math.floor(Math.random() * 1e9)); $("seed").value = state.seed; redraw();
    });
    $("export").addEventListener("click", exportView);
  }

  function bindPlane() {
    const plane = $("plane");
    let drag = null;
    plane.addEventListener("pointerdown", (e) => {
      drag = { x: e.clientX, y: e.clientY, cx: state.cx, cy: state.cy };
      plane.setPointerCapture(e.pointerId);
      plane.classList.add("dragging");
    });
    plane.addEventListener("pointermove", (e) => {
      if (!drag) return;
      state.cx = drag.cx - (e.clientX - drag.x);
      state.cy = drag.cy - (e.clientY - drag.y);
      draw();
    });
    const end = () => { if (drag) { drag = null; plane.classList.remove("dragging"); writeHash(); } };
    plane.addEventListener("pointerup", end);
    plane.addEventListener("pointercancel", end);
    plane.addEventListener("wheel", (e) => {
      e.preventDefault();
      const rect = plane.getBoundingClientRect();
      const mx = e.clientX - rect.left, my = e.clientY - rect.top;
      const { left, top } = viewBox();
      const zoom = Number(Math.min(64, Math.max(1 / 64, state.zoom * (e.deltaY < 0 ? 1.25 : 0.8))).toPrecision(6));
      // The point under the cursor stays there.
      const u = (left + mx) / state.zoom, v = (top + my) / state.zoom;
      state.cx = Math.round(u * zoom - mx + plane.clientWidth / 2);
      state.cy = Math.round(v * zoom - my + plane.clientHeight / 2);
      state.zoom = zoom;
      $("zoom").value = String(zoom);
      redraw();
    }, { passive: false });
    window.addEventListener("resize", draw);
  }

  function exportView() {
    const { w, h, left, top } = viewBox();
    const size = $("export-size").value.trim() || (w + "x" + h);
    const q = viewQuery();
    q.set("x", String(left)); q.set("y", String(top)); q.set("size", size);
    $("status").textContent = "writing…";
    fetch("/export?" + q.toString(), { method: "POST", headers: { "X-Ipfn": "1" } }).then(async (r) => {
      if (!r.ok) { $("status").textContent = await r.text(); return; }
      const out = await r.json();
      $("command").textContent = out.command;
      $("export-link").href = "/exports/" + encodeURIComponent(out.file);
      $("export-link").textContent = out.path;
      $("status").textContent = "written" + (out.note ? ` (${out.note})` : "");
    }).catch((e) => { $("status").textContent = String(e); });
  }

  function showModel() {
    const m = info.model;
    if (!m) { $("model").textContent = "no checkpoint yet: the plane appears after the run's first"; return; }
    const k = m.k.map((v) => (typeof v === "number" ? v.toFixed(3) : "NaN")).join(", ");
    $("model").textContent = `${m.description} · ${m.dims}D, ${m.channels} channels, K = (${k}) · ${m.device}`;
    $("tile-row").hidden = m.dims !== 2;
    $("guide-row").hidden = !m.guided;
    $("density-row").hidden = !m.density;
    $("slice-row").hidden = m.dims !== 3;
    $("map-row").hidden = m.maps.length === 0;
    const select = $("map");
    // A map set's maps, then the material lit from them (index: the number of maps).
    const views = m.maps.length === 0 ? 0 : m.maps.length + 1;
    if (select.options.length !== views) {
      select.textContent = "";
      m.maps.forEach((map, i) => {
        const o = document.createElement("option");
        o.value = String(i); o.textContent = map.name + (map.normal ? " (normal, as colours)" : "");
        select.appendChild(o);
      });
      if (views > 0) {
        const o = document.createElement("option");
        o.value = String(m.maps.length); o.textContent = "material, lit";
        select.appendChild(o);
      }
      select.value = String(state.map);
    }
  }

  // ---- run: plots, previews, config ----
  const SERIES = [
    ["Wasserstein estimate", ["wasserstein"]],
    ["gradient penalty", ["penalty"]],
    ["generator loss", ["generator_loss"]],
    ["K per axis", ["k_depth", "k_rows", "k_cols"]],
    ["SIFID (lower is better)", ["sifid"]],
    ["structure (lower is better)", ["structure"], "structure_"],
    ["repeat (near 1: a grid)", ["repeat"]],
  ];
  const COLOURS = ["#0b6eaf", "#c0392b", "#27ae60", "#8e44ad", "#d68910", "#555555"];
  const COLOUR_NAMES = ["blue", "red", "green", "purple", "orange", "gray"];

  function plot(title, names, metrics) {
    const xs = metrics.iteration || [];
    const lines = names.filter((n) => metrics[n]).map((n) => ({ n, ys: metrics[n] }));
    const points = lines.map(({ ys }) => xs.map((x, i) => [x, ys[i]]).filter(([x, y]) => x !== null && y !== null && isFinite(y)));
    const all = points.flat();
    if (all.length === 0) return null;
    const W = 300, H = 150, P = 34;
    const x0 = Math.min(...all.map((p) => p[0])), x1 = Math.max(...all.map((p) => p[0]));
    const y0 = Math.min(...all.map((p) => p[1])), y1 = Math.max(...all.map((p) => p[1]));
    const sx = (x) => P + (x1 > x0 ? (x - x0) / (x1 - x0) : 0.5) * (W - P - 6);
    const sy = (y) => H - 16 - (y1 > y0 ? (y - y0) / (y1 - y0) : 0.5) * (H - 24);
    const ns = "http://www.w3.org/2000/svg";
    const svg = document.createElementNS(ns, "svg");
    svg.setAttribute("width", W); svg.setAttribute("height", H);
    const add = (tag, attrs, text) => {
      const el = document.createElementNS(ns, tag);
      for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
      if (text !== undefined) el.textContent = text;
      svg.appendChild(el);
      return el;
    };
    const fmt = (v) => (Math.abs(v) >= 1000 || (Math.abs(v) < 0.01 && v !== 0) ? v.toExponential(1) : v.toFixed(2));
    add("text", { x: 2, y: 10, "font-size": 10 }, fmt(y1));
    add("text", { x: 2, y: H - 16, "font-size": 10 }, fmt(y0));
    add("text", { x: P, y: H - 3, "font-size": 10 }, String(x0));
    add("text", { x: W - 6, y: H - 3, "font-size": 10, "text-anchor": "end" }, String(x1));
    points.forEach((pts, i) => {
      const d = pts.map(([x, y]) => `${sx(x).toFixed(1)},${sy(y).toFixed(1)}`).join(" ");
      const line = add("polyline", { points: d, fill: "none", stroke: COLOURS[i % COLOURS.length], "stroke-width": 1.2 });
      line.dataset.series = lines[i].n;
      if (pts.length < 40) pts.forEach(([x, y]) => add("circle", { cx: sx(x), cy: sy(y), r: 2, fill: COLOURS[i % COLOURS.length] }));
    });
    const figure = document.createElement("figure");
    const caption = document.createElement("figcaption");
    const latest = (i) => fmt(points[i][points[i].length - 1]?.[1] ?? NaN);
    const last = lines.length === 1 ? latest(0)
      : lines.map(({ n }, i) => `${n.replace("k_", "").replace("structure_", "")} ${latest(i)} (${COLOUR_NAMES[i % COLOURS.length]})`).join(", ");
    caption.textContent = `${title}: ${last}`;
    figure.append(caption, svg);
    return figure;
  }

  function showRun(run) {
    $("run").hidden = false;
    $("run-folder").textContent = run.folder;
    $("run-state").textContent = run.state;
    $("run-state").className = "state-" + run.state;
    $("run-iteration").textContent = String(run.iteration);
    const plots = $("plots");
    plots.textContent = "";
    for (const [title, names, perMap] of SERIES) {
      // A map set's run has one structure column per map: those lines replace their mean.
      const maps = perMap ? Object.keys(run.metrics).filter((n) => n.startsWith(perMap)) : [];
      const figure = plot(title, maps.length ? maps : names, run.metrics);
      if (figure) plots.appendChild(figure);
    }
    const strip = $("previews");
    const have = new Set([...strip.querySelectorAll("img")].map((i) => i.dataset.name));
    for (const name of run.previews) {
      if (have.has(name)) continue;
      const figure = document.createElement("figure");
      const img = document.createElement("img");
      img.loading = "lazy";
      img.dataset.name = name;
      img.src = (REPORT ? "previews/" : "/preview/") + encodeURIComponent(name);
      const caption = document.createElement("figcaption");
      caption.textContent = "iteration " + Number(name.replace(/\D/g, ""));
      figure.append(img, caption);
      strip.appendChild(figure);
    }
    $("config").textContent = run.config;
  }

  async function poll() {
    try {
      const fresh = await (await fetch("/api/info")).json();
      const changed = !info || JSON.stringify(fresh.model) !== JSON.stringify(info.model);
      info = fresh;
      if (changed) { showModel(); draw(); }
      if (info.run) showRun(await (await fetch("/api/run")).json());
    } catch (e) {
      $("status").textContent = "the server does not answer: " + e;
    }
    // A run is polled every 2 s; a model file every 5 s (it may be replaced).
    setTimeout(poll, info && info.run ? 2000 : 5000);
  }

  if (REPORT) {
    document.body.classList.add("report");
    showRun(REPORT);
  } else {
    readHash();
    bindControls();
    bindPlane();
    poll();
  }
  window.ipfnView = { state, draw, redraw, info: () => info };
})();
