// murk live: pulls restored frames from the server and shows raw | restored; every text from the server or the
// user is set with textContent (never parsed as HTML). A frame comes as two JPEGs in one response, raw then
// restored (X-Murk-Raw-Bytes long): the same JPEGs Foxglove publishes when a client subscribes there.
"use strict";
(function () {
  const token = new URLSearchParams(location.search).get("token") || "";
  const headers = token ? { "X-Murk-Token": token } : {};
  const $ = (id) => document.getElementById(id);
  const stats = { frames: 0, lastFrame: -1, skipped: 0, latencies: [], latencyMedianMs: null, pageFps: 0, method: "", changes: 0, errors: 0 };
  window.murkStats = stats;
  const arrivals = [];
  let methods = {};
  let split = 0.5;
  let lastBitmaps = null; // { raw, restored }: the frame shown

  function say(text, isError) {
    const m = $("message");
    m.textContent = text;
    m.className = isError ? "error" : "";
    if (isError) stats.errors += 1;
  }

  async function api(path, body) {
    const init = { headers: Object.assign({}, headers), cache: "no-store" };
    if (body !== undefined) {
      init.method = "POST";
      init.headers["Content-Type"] = "application/json";
      init.body = JSON.stringify(body);
    }
    const r = await fetch(path, init);
    let data = {};
    try { data = await r.json(); } catch (e) { data = { error: "the server answered " + r.status + " without a message" }; }
    if (!r.ok) throw new Error(data.error || ("HTTP " + r.status));
    return data;
  }

  function median(a) {
    if (!a.length) return null;
    const s = a.slice().sort((x, y) => x - y);
    const h = s.length >> 1;
    return s.length % 2 ? s[h] : (s[h - 1] + s[h]) / 2;
  }

  // raw and restored may differ in size (one shared with Foxglove at full resolution): each canvas takes its
  // image's size and the style scales both alike; the split view draws raw at the restored image's size
  function draw(bmps) {
    const layout = $("views").dataset.layout;
    if (layout === "split") {
      const w = bmps.restored.width, h = bmps.restored.height;
      const c = $("split-canvas");
      if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
      const ctx = c.getContext("2d");
      const x = Math.round(split * w);
      ctx.drawImage(bmps.raw, 0, 0, w, h);
      if (x < w) ctx.drawImage(bmps.restored, x, 0, w - x, h, x, 0, w - x, h);
      ctx.fillStyle = "#fff";
      ctx.fillRect(Math.max(0, x - 1), 0, 2, h);
    } else {
      for (const id of ["raw", "restored"]) {
        const bmp = bmps[id], c = $(id);
        if (c.width !== bmp.width || c.height !== bmp.height) { c.width = bmp.width; c.height = bmp.height; }
        c.getContext("2d").drawImage(bmp, 0, 0);
      }
    }
  }

  async function decode(blob, rawBytes) {
    if (!(rawBytes > 0 && rawBytes < blob.size)) throw new Error("a frame without its two images (X-Murk-Raw-Bytes)");
    const [raw, restored] = await Promise.all([
      createImageBitmap(blob.slice(0, rawBytes, "image/jpeg")),
      createImageBitmap(blob.slice(rawBytes, blob.size, "image/jpeg")),
    ]);
    return { raw, restored };
  }

  function next(after) {
    return fetch("/api/frame?after=" + after, { headers, cache: "no-store" }).then(async (r) => {
      if (r.status !== 200) return { r };
      return { r, blob: await r.blob() };
    });
  }

  async function frames() {
    let after = -1;
    let pending = next(after);
    for (;;) {
      let got;
      try {
        got = await pending;
      } catch (e) {
        say("connection to murk lost; retrying", true);
        await new Promise((res) => setTimeout(res, 1000));
        pending = next(after);
        continue;
      }
      const r = got.r;
      if (r.status === 204) { pending = next(after); continue; } // no newer frame yet (or the source ended)
      if (!r.ok) {
        let msg = "HTTP " + r.status;
        try { msg = (await r.json()).error || msg; } catch (e) { /* keep the status */ }
        say(msg, true);
        await new Promise((res) => setTimeout(res, 1000));
        pending = next(after);
        continue;
      }
      const index = Number(r.headers.get("X-Murk-Frame"));
      const captureMs = Number(r.headers.get("X-Murk-Capture-Ms"));
      const method = r.headers.get("X-Murk-Method") || "";
      const rawBytes = Number(r.headers.get("X-Murk-Raw-Bytes"));
      pending = next(index); // ask for the next frame while this one is decoded and drawn
      let bmps;
      try {
        bmps = await decode(got.blob, rawBytes);
      } catch (e) {
        say("frame " + index + ": " + e.message, true);
        after = index;
        continue;
      }
      const now = Date.now(); // the frame has arrived and is decoded: glass-to-page ends here
      if (after >= 0 && index > after + 1) stats.skipped += index - after - 1;
      after = index;
      if (lastBitmaps) { lastBitmaps.raw.close(); lastBitmaps.restored.close(); }
      lastBitmaps = bmps;
      draw(bmps);
      stats.frames += 1;
      stats.lastFrame = index;
      if (method !== stats.method) { stats.method = method; stats.changes += 1; $("restored-caption").textContent = "restored: " + method; }
      stats.latencies.push(now - captureMs);
      if (stats.latencies.length > 300) stats.latencies.shift();
      stats.latencyMedianMs = median(stats.latencies);
      arrivals.push(performance.now());
      while (arrivals.length && arrivals[0] < performance.now() - 2000) arrivals.shift();
      stats.pageFps = arrivals.length > 1 ? (arrivals.length - 1) * 1000 / (arrivals[arrivals.length - 1] - arrivals[0]) : 0;
      document.body.dataset.state = "running";
    }
  }

  function show(id, value) { $(id).textContent = value === null || value === undefined ? "-" : String(value); }

  async function status() {
    try {
      const s = await api("/api/status");
      show("source", s.source);
      show("fps", s.fps);
      show("dropped", s.dropped);
      show("frame", s.frame);
      const water = s.estimates && typeof s.estimates.visibility_m === "number" ? s.estimates : null;
      $("water").hidden = !water; // the water method's estimate of the latest frame (uncalibrated metres)
      if (water) {
        const far = water.far_distance_m;
        show("visibility", water.visibility_measurable || typeof far !== "number"
          ? water.visibility_m.toFixed(1) + " m" : "beyond " + far.toFixed(1) + " m");
      }
      const rec = $("recording");
      rec.hidden = !s.recording;
      rec.textContent = s.recording ? "recording " + s.recording : "";
      $("record").setAttribute("aria-pressed", s.recording ? "true" : "false");
      $("record").textContent = s.recording ? "stop recording" : "record";
      const ended = $("ended");
      ended.hidden = !s.ended;
      ended.textContent = s.ended ? "source ended: " + s.ended : "";
      if (s.ended) document.body.dataset.state = "ended";
      const stopped = s.recording_stopped && !s.recording; // a write failed (a full disk): why, until the next recording
      $("rec-stopped").hidden = !stopped;
      $("rec-stopped").textContent = stopped ? "recording stopped: " + s.recording_stopped : "";
      if (document.activeElement !== $("method") && !$("method").value) $("method").value = s.method;
      if (s.last_error) $("ended").title = s.last_error;
    } catch (e) {
      say("status: " + e.message, true);
    }
    show("page-fps", stats.pageFps ? stats.pageFps.toFixed(1) : null);
    show("latency", stats.latencyMedianMs === null ? null : Math.round(stats.latencyMedianMs));
    show("skipped", stats.skipped);
  }

  function optionFields() {
    const box = $("options");
    const keep = {};
    for (const input of box.querySelectorAll("input")) if (input.value) keep[input.name] = input.value;
    box.replaceChildren();
    const seen = new Set();
    const spec = $("method").value.split("?")[0];
    for (const stage of spec.split("+").map((s) => s.trim())) {
      for (const opt of methods[stage] || []) {
        if (seen.has(opt.name)) continue;
        seen.add(opt.name);
        const label = document.createElement("label");
        label.textContent = opt.name + " ";
        const input = document.createElement("input");
        input.name = opt.name;
        input.placeholder = opt.default === null ? "default" : String(opt.default);
        input.title = opt.name + ": " + opt.type + " (default " + String(opt.default) + ")" + (opt.help ? ": " + opt.help : "");
        if (keep[opt.name]) input.value = keep[opt.name];
        label.appendChild(input);
        box.appendChild(label);
      }
    }
  }

  async function loadMethods() {
    try {
      const m = await api("/api/methods");
      const list = $("methods");
      for (const entry of m.methods) {
        methods[entry.name] = entry.options;
        const o = document.createElement("option");
        o.value = entry.name;
        list.appendChild(o);
      }
      for (const chain of m.suggested) {
        const o = document.createElement("option");
        o.value = chain;
        list.appendChild(o);
      }
      $("method").value = m.current;
      optionFields();
    } catch (e) {
      say("methods: " + e.message, true);
    }
  }

  $("method").addEventListener("change", optionFields);
  $("method-form").addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const options = {};
    for (const input of $("options").querySelectorAll("input")) if (input.value.trim()) options[input.name] = input.value.trim();
    try {
      const r = await api("/api/method", { method: $("method").value.trim(), options });
      say("method: " + r.method, false);
    } catch (e) {
      say(e.message, true);
    }
  });
  $("snapshot").addEventListener("click", async () => {
    try {
      const r = await api("/api/snapshot", {});
      say("snapshot of frame " + r.frame + " saved: " + r.files.join(", "), false);
    } catch (e) {
      say(e.message, true);
    }
  });
  $("record").addEventListener("click", async () => {
    const on = $("record").getAttribute("aria-pressed") !== "true";
    try {
      const r = await api("/api/record", { on });
      $("record").setAttribute("aria-pressed", r.recording ? "true" : "false");
      say(r.recording ? "recording to " + r.recording : "recording saved: " + (r.saved || "no frame recorded"), false);
    } catch (e) {
      say(e.message, true);
    }
  });
  for (const radio of document.querySelectorAll("input[name=layout]")) {
    radio.addEventListener("change", () => {
      const layout = document.querySelector("input[name=layout]:checked").value;
      $("views").dataset.layout = layout;
      $("splitview").hidden = layout !== "split";
      $("split").disabled = layout !== "split";
      if (lastBitmaps) draw(lastBitmaps);
    });
  }
  $("split").addEventListener("input", () => { split = Number($("split").value) / 100; if (lastBitmaps) draw(lastBitmaps); });

  loadMethods();
  status();
  setInterval(status, 500);
  frames();
})();
