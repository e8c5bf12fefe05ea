// The comparison report's viewers and tables. No library, no network: the page's data sits in the
// <script id="taa-data"> element and the images are the study's own PNGs, by relative path.
(function () {
  "use strict";
  const model = JSON.parse(document.getElementById("taa-data").textContent);
  const SVGNS = "http://www.w3.org/2000/svg";
  const PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
                   "#bcbd22", "#17becf"];
  const MODES = { image: "image", ssim: "SSIM map", flip: "FLIP map" };
  const ZMIN = 1 / 16, ZMAX = 256;
  const images = new Map();          // path -> {img, ok, waiting: [callbacks]}
  const byImage = new Map();         // path -> {viewer, layer, mode, frame}: where a table link opens
  const viewers = [];
  const linkBox = document.getElementById("taa-link");
  let active = null;
  let lastPointer = null;
  window.addEventListener("mousemove", (e) => { setTimeout(() => { lastPointer = [e.screenX, e.screenY]; }, 0); }, true);

  function load(path, done) {
    let e = images.get(path);
    if (!e) {
      e = { img: new Image(), ok: false, failed: false, waiting: [] };
      images.set(path, e);
      e.img.onload = () => { e.ok = true; e.waiting.splice(0).forEach((f) => f(e)); };
      e.img.onerror = () => {
        // Chrome logs no error for a missing file:// image: say it, so a broken report shows.
        console.error("taa report: cannot load image " + path);
        e.failed = true;
        e.waiting.splice(0).forEach((f) => f(e));
      };
      e.img.src = path;
    }
    if (done) { if (e.ok || e.failed) done(e); else e.waiting.push(done); }
    return e;
  }

  function fmtNum(v) {
    if (v === null || v === undefined) return "–";
    const a = Math.abs(v);
    return a !== 0 && (a < 1e-3 || a >= 1e5) ? v.toExponential(3) : (+v.toPrecision(5)).toString();
  }

  function el(tag, attrs, text) {
    const e = document.createElement(tag);
    for (const k in attrs || {}) e.setAttribute(k, attrs[k]);
    if (text !== undefined) e.textContent = text;
    return e;
  }

  class Viewer {
    constructor(root, spec, index) {
      this.root = root; this.spec = spec; this.index = index;
      this.canvas = root.querySelector("canvas");
      this.ctx = this.canvas.getContext("2d");
      this.stage = root.querySelector(".stage");
      this.statusEl = root.querySelector(".status");
      [this.w, this.h] = spec.size;
      this.layer = 0; this.last = 0; this.mode = "image"; this.frame = 0;
      this.zoom = null; this.px = 0; this.py = 0; this.ev = 0; this.awake = false;
      this.cursor = null;
      this.makeFilter();
      this.makeButtons();
      this.bind();
      if (spec.kind === "ghosting") this.makeGhost();
      spec.layers.forEach((L, li) => {
        L.images.forEach((p, f) => { if (!byImage.has(p)) byImage.set(p, { viewer: this, layer: li, mode: "image", frame: f }); });
        if (L.ssim && !byImage.has(L.ssim)) byImage.set(L.ssim, { viewer: this, layer: li, mode: "ssim", frame: 0 });
        if (L.flip && !byImage.has(L.flip)) byImage.set(L.flip, { viewer: this, layer: li, mode: "flip", frame: 0 });
      });
    }

    // Exposure: linear light of the display image times 2^EV (the filter works in linearRGB).
    makeFilter() {
      const f = document.createElementNS(SVGNS, "filter");
      this.filterId = "taa-exp-" + this.index;
      f.setAttribute("id", this.filterId);
      f.setAttribute("color-interpolation-filters", "linearRGB");
      const ct = document.createElementNS(SVGNS, "feComponentTransfer");
      this.funcs = ["feFuncR", "feFuncG", "feFuncB"].map((n) => {
        const fn = document.createElementNS(SVGNS, n);
        fn.setAttribute("type", "linear");
        fn.setAttribute("slope", "1");
        ct.appendChild(fn);
        return fn;
      });
      f.appendChild(ct);
      document.getElementById("taa-filters").appendChild(f);
    }

    makeButtons() {
      const bar = this.root.querySelector(".layers");
      this.layerButtons = this.spec.layers.map((L, i) => {
        const b = el("button", { type: "button", "data-layer": L.label });
        if (i < 9) b.appendChild(el("span", { class: "key" }, String(i + 1)));
        b.appendChild(document.createTextNode(L.label));
        b.addEventListener("click", () => { this.activate(); this.setLayer(i); });
        bar.appendChild(b);
        return b;
      });
      const c = this.root.querySelector(".controls");
      const btn = (label, key, fn, attrs) => {
        const b = el("button", Object.assign({ type: "button" }, attrs || {}));
        if (key) b.appendChild(el("span", { class: "key" }, key));
        b.appendChild(document.createTextNode(label));
        b.addEventListener("click", () => { this.activate(); fn(); });
        c.appendChild(b);
        return b;
      };
      this.modeButtons = {};
      for (const [m, key] of [["image", "i"], ["ssim", "s"], ["flip", "f"]]) {
        if (m !== "image" && !this.spec.layers.some((L) => L[m])) continue;
        this.modeButtons[m] = btn(MODES[m], key, () => this.setMode(m), { "data-mode": m });
      }
      c.appendChild(el("span", { class: "sep" }));
      btn("zoom out", "−", () => this.zoomBy(-1));
      btn("fit", "0", () => this.fit());
      btn("zoom in", "+", () => this.zoomBy(1));
      c.appendChild(el("span", { class: "sep" }));
      btn("EV", "E", () => this.setEv(this.ev - 0.5));
      this.evLabel = el("span", { class: "ev" }, "0.0 EV");
      c.appendChild(this.evLabel);
      btn("EV", "e", () => this.setEv(this.ev + 0.5));
      btn("reset", "x", () => this.setEv(0));
    }

    bind() {
      const st = this.stage;
      let drag = null;
      // The pointer makes a viewer active only by moving: a scroll that carries another viewer under
      // a still pointer (e.g. after a table link) must not take the keys away.
      st.addEventListener("mousemove", (e) => {
        if (lastPointer && (e.screenX !== lastPointer[0] || e.screenY !== lastPointer[1])) this.activate();
      });
      st.addEventListener("mousedown", (e) => {
        this.activate();
        drag = { x: e.clientX, y: e.clientY, px: this.px, py: this.py };
        st.classList.add("dragging");
        e.preventDefault();
      });
      window.addEventListener("mouseup", () => { drag = null; st.classList.remove("dragging"); });
      window.addEventListener("mousemove", (e) => {
        if (drag) {
          this.px = drag.px + Math.round(e.clientX - drag.x);
          this.py = drag.py + Math.round(e.clientY - drag.y);
          this.changed();
        }
      });
      st.addEventListener("mousemove", (e) => {
        const r = this.canvas.getBoundingClientRect();
        const x = Math.floor((e.clientX - r.left - this.px) / this.zoom);
        const y = Math.floor((e.clientY - r.top - this.py) / this.zoom);
        this.cursor = x >= 0 && y >= 0 && x < this.w && y < this.h ? [x, y] : null;
        this.status();
      });
      st.addEventListener("wheel", (e) => {
        e.preventDefault();
        this.activate();
        const r = this.canvas.getBoundingClientRect();
        this.zoomBy(e.deltaY < 0 ? 1 : -1, e.clientX - r.left, e.clientY - r.top);
      }, { passive: false });
      this.root.addEventListener("click", () => this.activate());
    }

    makeGhost() {
      this.slider = this.root.querySelector(".slider");
      this.frameLabel = this.root.querySelector(".frame-id");
      this.curve = this.root.querySelector("svg.curve");
      this.metricSel = this.root.querySelector(".curve-metric");
      const metrics = [];
      this.spec.layers.forEach((L) => Object.keys(L.metrics || {}).forEach((m) => { if (!metrics.includes(m)) metrics.push(m); }));
      metrics.forEach((m) => this.metricSel.appendChild(el("option", { value: m }, m)));
      if (metrics.includes("psnr")) this.metricSel.value = "psnr";
      this.slider.addEventListener("input", () => { this.activate(); this.setFrame(+this.slider.value); });
      this.metricSel.addEventListener("change", () => this.drawCurve());
      this.curve.addEventListener("click", (e) => {
        const r = this.curve.getBoundingClientRect();
        const u = ((e.clientX - r.left) / r.width * 640 - 44) / (640 - 54);
        const n = this.spec.frames.length;
        this.activate();
        this.setFrame(Math.round(Math.min(1, Math.max(0, u)) * (n - 1)));
      });
    }

    activate() {
      if (active === this) return;
      if (active) active.root.classList.remove("active");
      active = this;
      this.root.classList.add("active");
    }

    src() {
      const L = this.spec.layers[this.layer];
      if (this.mode !== "image" && L[this.mode]) return L[this.mode];
      return L.images[Math.min(this.frame, L.images.length - 1)];
    }

    wake() {
      if (this.awake) return;
      this.awake = true;
      this.layout(true);
      this.show();
    }

    layout(refit) {
      const cw = Math.max(50, this.stage.clientWidth);
      const ch = Math.max(120, Math.min(640, Math.round(0.7 * window.innerHeight), Math.round(cw * this.h / this.w)));
      const dpr = window.devicePixelRatio || 1;
      this.cw = cw; this.ch = ch; this.dpr = dpr;
      this.canvas.style.height = ch + "px";
      this.canvas.width = Math.round(cw * dpr);
      this.canvas.height = Math.round(ch * dpr);
      if (refit || this.zoom === null) this.fit(true);
    }

    fitZoom() {
      const f = Math.min(this.cw / this.w, this.ch / this.h);
      return f >= 1 ? Math.floor(f) : f;
    }

    fit(quiet) {
      this.zoom = this.fitZoom();
      this.px = Math.round((this.cw - this.w * this.zoom) / 2);
      this.py = Math.round((this.ch - this.h * this.zoom) / 2);
      if (!quiet) this.changed();
    }

    // Zoom steps are powers of two, about a point of the canvas (default: its centre); offsets stay
    // whole CSS pixels so every image pixel becomes the same number of screen pixels.
    zoomBy(dir, cx, cy) {
      if (cx === undefined) { cx = this.cw / 2; cy = this.ch / 2; }
      const l = Math.log2(this.zoom);
      const z = Math.min(ZMAX, Math.max(ZMIN, Math.pow(2, dir > 0 ? Math.floor(l + 1e-9) + 1 : Math.ceil(l - 1e-9) - 1)));
      const u = (cx - this.px) / this.zoom, v = (cy - this.py) / this.zoom;
      this.zoom = z;
      this.px = Math.round(cx - u * z);
      this.py = Math.round(cy - v * z);
      this.changed();
    }

    changed() {
      this.draw();
      if (linkBox && linkBox.checked) {
        for (const o of viewers) {
          if (o !== this && o.w === this.w && o.h === this.h && o.awake) {
            o.zoom = this.zoom; o.px = this.px; o.py = this.py;
            o.draw();
          }
        }
      }
    }

    setLayer(i) {
      if (i < 0 || i >= this.spec.layers.length) return;
      if (i !== this.layer) { this.last = this.layer; this.layer = i; }
      this.show();
    }

    setMode(m) { if (MODES[m]) { this.mode = m; this.show(); } }

    setEv(ev) {
      this.ev = Math.max(-10, Math.min(10, ev));
      const s = String(Math.pow(2, this.ev));
      this.funcs.forEach((f) => f.setAttribute("slope", s));
      this.evLabel.textContent = (this.ev >= 0 ? "+" : "") + this.ev.toFixed(1) + " EV";
      this.draw();
    }

    setFrame(f) {
      if (this.spec.kind !== "ghosting") return;
      const n = this.spec.frames.length;
      this.frame = Math.max(0, Math.min(n - 1, f));
      this.slider.value = String(this.frame);
      this.show();
      // The neighbours of this frame, so that stepping through the sequence does not wait.
      for (const d of [1, -1]) {
        const k = this.frame + d;
        if (k >= 0 && k < n) this.spec.layers.forEach((L) => load(L.images[k]));
      }
    }

    show() {
      if (!this.awake) { this.wake(); return; }
      const path = this.src();
      this.root.dataset.ready = "0";
      load(path, () => {
        if (this.src() === path) { this.draw(); }
      });
      this.draw();
      this.layerButtons.forEach((b, i) => b.classList.toggle("on", i === this.layer));
      for (const m in this.modeButtons) this.modeButtons[m].classList.toggle("on", m === this.mode);
      if (this.spec.kind === "ghosting") {
        this.frameLabel.textContent = "id " + this.spec.frames[this.frame] + " (" + (this.frame + 1) + " of " + this.spec.frames.length + ")";
        this.drawCurve();
      }
      // Every layer of what is shown now, so that flipping is instant.
      this.spec.layers.forEach((L) => {
        load(L.images[Math.min(this.frame, L.images.length - 1)]);
        if (L.ssim) load(L.ssim);
        if (L.flip) load(L.flip);
      });
    }

    draw() {
      if (!this.awake) return;
      const ctx = this.ctx, path = this.src(), e = images.get(path);
      ctx.setTransform(1, 0, 0, 1, 0, 0);
      ctx.filter = "none";
      ctx.fillStyle = "#202124";
      ctx.fillRect(0, 0, this.canvas.width, this.canvas.height);
      const d = this.root.dataset;
      d.layer = this.spec.layers[this.layer].label;
      d.mode = this.mode;
      d.src = path;
      d.zoom = String(this.zoom);
      d.px = String(this.px);
      d.py = String(this.py);
      d.ev = String(this.ev);
      d.frame = String(this.frame);
      if (e && e.ok) {
        ctx.setTransform(this.dpr, 0, 0, this.dpr, 0, 0);
        ctx.imageSmoothingEnabled = false;
        const exposed = this.ev !== 0 && (this.mode === "image" || !this.spec.layers[this.layer][this.mode]);
        ctx.filter = exposed ? "url(#" + this.filterId + ")" : "none";
        ctx.drawImage(e.img, this.px, this.py, this.w * this.zoom, this.h * this.zoom);
        ctx.filter = "none";
        d.ready = "1";
      } else if (e && e.failed) {
        d.ready = "failed";
      }
      this.status();
    }

    status() {
      const L = this.spec.layers[this.layer];
      const noMap = this.mode !== "image" && !L[this.mode];
      let s = L.label + " · " + (noMap ? "image (no " + MODES[this.mode] + " for " + L.label + ")" : MODES[this.mode]) +
        " · zoom " + fmtNum(this.zoom) + "× · " + (this.ev >= 0 ? "+" : "") + this.ev.toFixed(1) + " EV";
      if (this.cursor) s += " · pixel (" + this.cursor[0] + ", " + this.cursor[1] + ")";
      const m = L.metrics || {};
      const parts = Object.keys(m).map((k) => {
        const v = Array.isArray(m[k]) ? m[k][this.frame] : m[k];
        return k + " " + fmtNum(v);
      });
      if (parts.length) s += "\n" + parts.join(" · ");
      this.statusEl.textContent = s;
    }

    drawCurve() {
      const svg = this.curve, metric = this.metricSel.value, n = this.spec.frames.length;
      while (svg.firstChild) svg.removeChild(svg.firstChild);
      const X0 = 44, X1 = 630, Y0 = 10, Y1 = 150;
      const vals = [];
      this.spec.layers.forEach((L) => ((L.metrics || {})[metric] || []).forEach((v) => { if (v !== null && isFinite(v)) vals.push(v); }));
      if (!vals.length) return;
      let lo = Math.min(...vals), hi = Math.max(...vals);
      if (hi === lo) { hi += 0.5; lo -= 0.5; }
      const x = (i) => X0 + (n > 1 ? i / (n - 1) : 0.5) * (X1 - X0);
      const y = (v) => Y1 - (v - lo) / (hi - lo) * (Y1 - Y0);
      const add = (tag, attrs, text) => { const e = document.createElementNS(SVGNS, tag); for (const k in attrs) e.setAttribute(k, attrs[k]); if (text !== undefined) e.textContent = text; svg.appendChild(e); return e; };
      add("line", { x1: X0, y1: Y1, x2: X1, y2: Y1, stroke: "#999" });
      add("line", { x1: X0, y1: Y0, x2: X0, y2: Y1, stroke: "#999" });
      add("text", { x: 2, y: Y0 + 8 }, fmtNum(hi));
      add("text", { x: 2, y: Y1 }, fmtNum(lo));
      add("text", { x: X0, y: 166 }, "frame " + this.spec.frames[0]);
      add("text", { x: X1 - 60, y: 166 }, "frame " + this.spec.frames[n - 1]);
      add("text", { x: X0 + 6, y: Y0 + 8 }, metric);
      this.spec.layers.forEach((L, li) => {
        const s = (L.metrics || {})[metric];
        if (!s) return;
        const pts = [];
        s.forEach((v, i) => { if (v !== null && isFinite(v)) pts.push(x(i).toFixed(1) + "," + y(v).toFixed(1)); });
        add("polyline", { class: "line" + (li === this.layer ? " current" : ""), points: pts.join(" "),
                          stroke: PALETTE[li % PALETTE.length], "data-layer": L.label });
      });
      add("line", { class: "marker", x1: x(this.frame), x2: x(this.frame), y1: Y0, y2: Y1, "data-frame": this.frame });
      let lx = X0 + 90;
      this.spec.layers.forEach((L, li) => {
        if (!(L.metrics || {})[metric]) return;
        add("text", { x: lx, y: Y0 + 8, style: "fill:" + PALETTE[li % PALETTE.length] }, L.label);
        lx += 8 + 6 * L.label.length;
      });
    }
  }

  function onKey(e) {
    const t = e.target;
    if (!active || e.ctrlKey || e.metaKey || e.altKey) return;
    if (t && (t.tagName === "INPUT" || t.tagName === "SELECT" || t.tagName === "TEXTAREA") && t.type !== "checkbox") return;
    const v = active, k = e.key;
    let done = true;
    if (k >= "1" && k <= "9") v.setLayer(+k - 1);
    else if (k === "ArrowRight" || k === "]") v.setLayer((v.layer + 1) % v.spec.layers.length);
    else if (k === "ArrowLeft" || k === "[") v.setLayer((v.layer - 1 + v.spec.layers.length) % v.spec.layers.length);
    else if (k === " ") v.setLayer(v.last);
    else if (k === "r") v.setLayer(0);
    else if (k === "i") v.setMode("image");
    else if (k === "s") v.setMode("ssim");
    else if (k === "f") v.setMode("flip");
    else if (k === "+" || k === "=") v.zoomBy(1);
    else if (k === "-" || k === "_") v.zoomBy(-1);
    else if (k === "0") v.fit();
    else if (k === "e") v.setEv(v.ev + 0.5);
    else if (k === "E") v.setEv(v.ev - 0.5);
    else if (k === "x") v.setEv(0);
    else if (k === ",") v.setFrame(v.frame - 1);
    else if (k === ".") v.setFrame(v.frame + 1);
    else done = false;
    if (done) e.preventDefault();
  }

  // Sortable tables: numbers by value (a cell's leading number; '–' last), anything else as text.
  function cellKey(td) {
    const s = td.textContent.trim();
    if (s.startsWith("∞")) return Infinity;
    const m = s.match(/^[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?/);
    return m ? parseFloat(m[0]) : (s === "–" || s === "" ? NaN : s);
  }
  function sortTable(table, col, th) {
    const dir = th.getAttribute("aria-sort") === "ascending" ? -1 : 1;
    table.querySelectorAll("th").forEach((h) => h.removeAttribute("aria-sort"));
    th.setAttribute("aria-sort", dir > 0 ? "ascending" : "descending");
    const body = table.tBodies[0];
    const rows = Array.from(body.rows).map((tr) => ({ tr, k: cellKey(tr.cells[col]) }));
    const numeric = rows.every((r) => typeof r.k === "number");
    rows.sort((a, b) => {
      if (numeric) {
        const an = isNaN(a.k), bn = isNaN(b.k);
        if (an || bn) return an === bn ? 0 : (an ? 1 : -1);        // missing values last either way
        return dir * (a.k - b.k);
      }
      return dir * String(a.k).localeCompare(String(b.k), undefined, { numeric: true });
    });
    rows.forEach((r) => body.appendChild(r.tr));
  }

  function init() {
    const specs = new Map(model.viewers.map((s) => [s.id, s]));
    document.querySelectorAll(".viewer").forEach((root) => {
      const spec = specs.get(root.id);
      if (spec) viewers.push(new Viewer(root, spec, viewers.length));
    });
    if (viewers.length) viewers[0].activate();
    document.addEventListener("keydown", onKey);
    if ("IntersectionObserver" in window) {
      const io = new IntersectionObserver((entries) => entries.forEach((en) => {
        if (en.isIntersecting) viewers.find((v) => v.root === en.target).wake();
      }), { rootMargin: "400px" });
      viewers.forEach((v) => io.observe(v.root));
    } else {
      viewers.forEach((v) => v.wake());
    }
    window.addEventListener("resize", () => viewers.forEach((v) => { if (v.awake) { v.layout(false); v.draw(); } }));
    document.querySelectorAll("table.sortable").forEach((table) => {
      table.querySelectorAll("th").forEach((th, col) => th.addEventListener("click", () => sortTable(table, col, th)));
    });
    document.querySelectorAll("a[data-img]").forEach((a) => a.addEventListener("click", (e) => {
      const at = byImage.get(a.dataset.img);
      if (!at) return;                 // not in a viewer: the browser opens the file
      e.preventDefault();
      const v = at.viewer;
      v.activate();
      v.wake();
      v.mode = at.mode;
      if (v.spec.kind === "ghosting") v.setFrame(at.frame);
      v.setLayer(at.layer);
      v.root.scrollIntoView({ block: "center" });
    }));
    window.taaReport = { viewers, byImage };
  }
  init();
})();
