/* pathdensity report viewer.
 *
 * Shows the selected image beside the reference on two canvases with a shared
 * zoom and pan, with exposure in stops, error views against the reference
 * (signed difference, relMSE, FLIP), a legend and a pixel readout. Inlined in
 * report.html: reads the JSON in #viewer-data, mounts into #viewer and stores
 * the instance as window.pathdensityViewer. Keys are listed in HELP. Every
 * redraw is synchronous, so a test can press a key and read the canvas at once.
 */
(function () {
  'use strict';

  // Half-float bit pattern -> value. Films stay in memory as raw half bits
  // (half the size of a Float32Array) and are looked up through this table.
  const HALF = new Float32Array(65536);
  for (let h = 0; h < 65536; h++) {
    const sign = h & 0x8000 ? -1 : 1, e = (h >> 10) & 31, m = h & 1023;
    HALF[h] = e === 0 ? sign * m * 2 ** -24
      : e === 31 ? (m ? NaN : sign * Infinity)
      : sign * (1024 + m) * 2 ** (e - 25);
  }

  // Evenly spaced stops, interpolated linearly in 8-bit sRGB.
  const COLORMAPS = {
    // ColorBrewer RdBu (11 classes) reversed: blue negative, neutral 0, red positive.
    diff: [[5, 48, 97], [33, 102, 172], [67, 147, 195], [146, 197, 222], [209, 229, 240], [247, 247, 247],
      [253, 219, 199], [244, 165, 130], [214, 96, 77], [178, 24, 43], [103, 0, 31]],
    // viridis, 17 samples.
    relmse: [[68, 1, 84], [72, 24, 106], [71, 45, 123], [66, 64, 134], [59, 82, 139], [51, 99, 141],
      [44, 114, 142], [38, 130, 142], [33, 145, 140], [31, 160, 136], [40, 174, 128], [63, 188, 115],
      [94, 201, 98], [132, 212, 75], [173, 220, 48], [216, 226, 25], [253, 231, 37]],
    // magma, 17 samples: the map NVIDIA's FLIP draws its error images with.
    flip: [[0, 0, 4], [10, 8, 34], [29, 17, 71], [54, 16, 107], [81, 18, 124], [106, 28, 129],
      [131, 38, 129], [156, 46, 127], [183, 55, 121], [208, 65, 111], [231, 82, 99], [245, 107, 92],
      [252, 137, 97], [254, 167, 114], [254, 196, 136], [253, 226, 163], [252, 253, 191]],
    // The image mode's legend: display levels from black to white.
    image: [[0, 0, 0], [255, 255, 255]],
  };
  const MODES = ['image', 'diff', 'relmse', 'flip'];
  const MODE_LABEL = { image: 'image', diff: 'signed difference', relmse: 'relMSE', flip: 'FLIP' };
  const NAN_RGBA = [255, 0, 255, 255];
  const BACKGROUND = [48, 48, 48, 255];
  const CACHE_BYTES = 256 * 2 ** 20; // decoded films kept; the least recently used go first
  const MAX_STOPS = 10;
  const HELP = 'Keys: 1–9 image · ↓/↑ or j/k next/previous · r toggle the reference on the left · ' +
    'e / E exposure +1 / −1 stop, 0 reset · m view: image → signed difference → relMSE → FLIP · ' +
    'f fit, + / − zoom, wheel zooms at the pointer, drag pans · , / . previous/next frame';

  function check(ok, message) {
    if (!ok) throw new Error(message);
  }

  function colour(table, t, out, o) {
    const p = (t < 0 ? 0 : t > 1 ? 1 : t) * (table.length - 1);
    const i = Math.min(Math.floor(p), table.length - 2), f = p - i, a = table[i], b = table[i + 1];
    for (let c = 0; c < 3; c++) out[o + c] = Math.round(a[c] + (b[c] - a[c]) * f);
    out[o + 3] = 255;
  }

  const srgb = (u) => (u <= 0.0031308 ? 12.92 * u : 1.055 * Math.pow(u, 1 / 2.4) - 0.055);

  // The report's PNG preview transform of one already scaled value; NaN stays NaN.
  function level(x) {
    if (x !== x) return NaN;
    return Math.round(255 * srgb(x < 0 ? 0 : x > 1 ? 1 : x));
  }

  // Colormap position of an unscaled error value; scale = E·2^stops.
  function errorT(mode, v, scale) {
    if (mode === 'diff') {
      const d = v * scale;
      return (d < -1 ? -1 : d > 1 ? 1 : d) * 0.5 + 0.5;
    }
    if (mode === 'relmse') return v > 0 ? Math.min(Math.max((Math.log10(v) + 4) / 4, 0), 1) : 0;
    return v; // FLIP is in [0, 1] already
  }

  const fmt = (v) => String(Number(v.toPrecision(3)));
  const fmtStops = (s) => (s < 0 ? '−' : '+') + Math.abs(s).toFixed(1) + ' stops';

  function fail(err) {
    console.error('pathdensity viewer: ' + ((err && err.stack) || err));
    document.body.dataset.status = 'error: viewer: ' + ((err && err.message) || err);
  }

  // Event handlers report their exceptions through the page status.
  const guard = (fn) => function (...args) {
    try {
      return fn.apply(this, args);
    } catch (err) {
      fail(err);
    }
  };

  function el(tag, cls, parent, text) {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text != null) e.textContent = text;
    if (parent) parent.appendChild(e);
    return e;
  }

  function mount(container, data) {
    const W = data.width, H = data.height, F = data.frames, E = data.exposure;
    const images = data.images, ref = data.reference == null ? null : data.reference;
    check([W, H, F].every((n) => Number.isInteger(n) && n > 0), `bad film size ${W}×${H}×${F}`);
    check(Number.isFinite(E) && E > 0, `bad exposure ${E}`);
    check(Array.isArray(images) && images.length > 0, 'no images');
    check(ref === null || (ref >= 0 && ref < images.length), `bad reference index ${ref}`);
    for (const im of images) {
      check(im.data.length === F && (!im.flip || im.flip.length === F), `${im.name}: not ${F} frames`);
    }
    const label = (i) => images[i].label || images[i].name;
    const st = {
      image: images[data.recommended] ? data.recommended : 0, frame: 0, stops: 0, mode: 'image',
      zoom: 1, panX: W / 2, panY: H / 2, showReference: false,
    };

    // --- decoding, cached per image and frame --------------------------------
    const cache = new Map();
    let cacheBytes = 0;
    function cached(key, make) {
      let v = cache.get(key);
      if (v) cache.delete(key);
      else {
        v = make();
        cacheBytes += v.byteLength;
      }
      cache.set(key, v);
      for (const [k, old] of cache) {
        if (cacheBytes <= CACHE_BYTES || k === key) break;
        cache.delete(k);
        cacheBytes -= old.byteLength;
      }
      return v;
    }
    function decode(b64, bytes, what) {
      const s = atob(b64);
      check(s.length === bytes, `${what}: ${s.length} bytes, expected ${bytes}`);
      return s;
    }
    function bits(i, f) {
      return cached(`h${i}/${f}`, () => {
        const n = W * H * 3, s = decode(images[i].data[f], 2 * n, `${images[i].name} frame ${f}`);
        const out = new Uint16Array(n);
        for (let k = 0; k < n; k++) out[k] = s.charCodeAt(2 * k) | (s.charCodeAt(2 * k + 1) << 8);
        return out;
      });
    }
    function flipMap(i, f) {
      if (!images[i].flip) return null;
      return cached(`f${i}/${f}`, () => {
        const s = decode(images[i].flip[f], W * H, `${images[i].name} FLIP frame ${f}`);
        const out = new Uint8Array(s.length);
        for (let k = 0; k < s.length; k++) out[k] = s.charCodeAt(k);
        return out;
      });
    }

    // --- values -----------------------------------------------------------------
    function checkPixel(i, f, x, y) {
      check(i >= 0 && i < images.length && f >= 0 && f < F && x >= 0 && x < W && y >= 0 && y < H &&
        [i, f, x, y].every(Number.isInteger), `no pixel ${x},${y} in image ${i} frame ${f}`);
    }
    function linear(i, f, x, y) {
      checkPixel(i, f, x, y);
      const b = bits(i, f), k = 3 * (y * W + x);
      return [HALF[b[k]], HALF[b[k + 1]], HALF[b[k + 2]]];
    }
    // Mean over RGB from value offset k; identical samples (Inf and NaN too) are no error.
    function pixelError(mode, a, r, k) {
      let sum = 0;
      for (let c = k; c < k + 3; c++) {
        if (a[c] === r[c]) continue;
        const x = HALF[a[c]], y = HALF[r[c]], d = x - y;
        sum += mode === 'diff' ? d : (d * d) / (y * y + 0.01);
      }
      return sum / 3;
    }
    // Unscaled error at a pixel: diff = mean(I − R), relmse, flip in [0, 1]; null if none.
    function errorValue(mode, i, f, x, y) {
      checkPixel(i, f, x, y);
      if (ref === null || mode === 'image') return null;
      const p = y * W + x;
      if (mode === 'flip') {
        if (i === ref) return 0;
        const m = flipMap(i, f);
        return m ? m[p] / 255 : null;
      }
      return pixelError(mode, bits(i, f), bits(ref, f), 3 * p);
    }

    // Display levels for every half value at the current exposure (-1 for NaN).
    let lut = null, lutStops = NaN;
    function displayLut() {
      if (lutStops !== st.stops) {
        const s = E * 2 ** st.stops;
        lut = new Int16Array(65536);
        for (let h = 0; h < 65536; h++) {
          const l = level(HALF[h] * s);
          lut[h] = l === l ? l : -1;
        }
        lutStops = st.stops;
      }
      return lut;
    }

    // RGBA of one view of the whole film, or null when there is nothing to show.
    function renderFilm(i, mode) {
      const n = W * H, out = new Uint8ClampedArray(4 * n), f = st.frame;
      if (mode === 'image') {
        const b = bits(i, f), l = displayLut();
        for (let p = 0, k = 0, o = 0; p < n; p++, k += 3, o += 4) {
          const r = l[b[k]], g = l[b[k + 1]], bl = l[b[k + 2]];
          if (r < 0 || g < 0 || bl < 0) out.set(NAN_RGBA, o);
          else {
            out[o] = r;
            out[o + 1] = g;
            out[o + 2] = bl;
            out[o + 3] = 255;
          }
        }
      } else if (mode === 'flip') {
        const m = i === ref ? null : flipMap(i, f);
        if (i !== ref && !m) return null;
        for (let p = 0; p < n; p++) colour(COLORMAPS.flip, m ? m[p] / 255 : 0, out, 4 * p);
      } else {
        const a = bits(i, f), r = bits(ref, f), s = E * 2 ** st.stops, table = COLORMAPS[mode];
        for (let p = 0; p < n; p++) {
          const v = pixelError(mode, a, r, 3 * p);
          if (v !== v) out.set(NAN_RGBA, 4 * p);
          else colour(table, errorT(mode, v, s), out, 4 * p);
        }
      }
      return out;
    }

    // --- page structure -----------------------------------------------------------
    container.textContent = '';
    container.classList.add('pdv');
    if (data.note) el('p', 'pdv-note', container, data.note);
    const panes = el('div', 'pdv-panes', container);
    const pane = (side) => {
      const p = el('div', 'pdv-pane pdv-' + side, panes);
      return { title: el('div', 'pdv-title', p), canvas: el('canvas', null, p), caption: el('div', 'pdv-caption', p), key: null };
    };
    const left = pane('left'), right = ref === null ? null : pane('right');
    const legend = el('div', 'pdv-legend', container);
    const legendTitle = el('span', 'pdv-legend-title', legend);
    const rampBox = el('div', 'pdv-ramp-box', legend);
    const ramp = el('div', 'pdv-ramp', rampBox);
    const ticks = el('div', 'pdv-ticks', rampBox);
    const tickEls = [0, 1, 2].map(() => el('span', null, ticks));
    const notice = el('span', 'pdv-notice', legend);
    const readout = el('div', 'pdv-readout', container, 'Move the pointer over an image for its values.');
    const imageRow = el('div', 'pdv-images', container);
    const imageButtons = images.map((im, i) => {
      const b = el('button', 'pdv-kind-' + im.kind, imageRow);
      b.type = 'button';
      b.title = im.caption || label(i);
      if (i < 9) el('span', 'pdv-key', b, String(i + 1));
      b.appendChild(document.createTextNode(label(i)));
      b.addEventListener('click', guard(() => {
        select(i);
        refresh();
      }));
      return b;
    });
    const controls = el('div', 'pdv-controls', container);
    const modeBox = el('div', 'pdv-modes', controls);
    el('span', null, modeBox, 'view (m) ');
    const modeButtons = MODES.map((m) => {
      const b = el('button', null, modeBox, MODE_LABEL[m]);
      b.type = 'button';
      b.disabled = m !== 'image' && ref === null;
      b.addEventListener('click', guard(() => {
        st.mode = m;
        refresh();
      }));
      return b;
    });
    function slider(name, min, max, step, set) {
      const lab = el('label', null, controls, name + ' ');
      const input = el('input', null, lab);
      Object.assign(input, { type: 'range', min, max, step, value: 0 });
      const out = el('output', null, lab);
      input.addEventListener('input', guard(() => {
        set(+input.value);
        refresh();
      }));
      return { lab, input, out };
    }
    const expo = slider('exposure (e/E/0)', -MAX_STOPS, MAX_STOPS, 0.5, (v) => { st.stops = v; });
    const frameCtl = slider('frame (,/.)', 0, F - 1, 1, (v) => { st.frame = v; });
    frameCtl.lab.hidden = F === 1;
    const fitButton = el('button', null, controls, 'fit (f)');
    fitButton.type = 'button';
    fitButton.addEventListener('click', guard(() => {
      fit();
      refresh();
    }));
    const zoomInfo = el('span', 'pdv-zoom', controls);
    el('p', 'pdv-help', container, HELP);

    // Fixed CSS size with the film's aspect; drawing is at device pixels.
    const dpr = window.devicePixelRatio || 1;
    const avail = container.clientWidth || 1300;
    let cssW = Math.max(64, Math.min(640, right ? Math.floor((avail - 16) / 2) : avail));
    let cssH = Math.round((cssW * H) / W);
    if (cssH > 640) {
      cssH = 640;
      cssW = Math.max(1, Math.round((640 * W) / H));
    }
    const cw = Math.round(cssW * dpr), ch = Math.round(cssH * dpr);
    for (const p of [left, right]) {
      if (!p) continue;
      Object.assign(p.canvas, { width: cw, height: ch });
      Object.assign(p.canvas.style, { width: cssW + 'px', height: cssH + 'px' });
      p.title.style.width = p.caption.style.width = cssW + 'px';
      // Drawing is putImageData only, so a CPU-backed canvas loses nothing and reads back fast.
      p.ctx = p.canvas.getContext('2d', { willReadFrequently: true });
      p.pixels = p.ctx.createImageData(cw, ch);
    }
    const bg32 = new Uint32Array(new Uint8ClampedArray(BACKGROUND).buffer)[0];

    // --- view: zoom = device pixels per image pixel, pan = image point at the centre
    const fitZoom = Math.min(cw / W, ch / H);
    function fit() {
      Object.assign(st, { zoom: fitZoom, panX: W / 2, panY: H / 2 });
    }
    function zoomAt(factor, mx, my) {
      const z = Math.min(Math.max(st.zoom * factor, fitZoom / 16), 512);
      st.panX += (mx - cw / 2) * (1 / st.zoom - 1 / z); // keeps the image point under (mx, my)
      st.panY += (my - ch / 2) * (1 / st.zoom - 1 / z);
      st.zoom = z;
      clampPan();
    }
    function clampPan() {
      st.panX = Math.min(Math.max(st.panX, 0), W);
      st.panY = Math.min(Math.max(st.panY, 0), H);
    }
    // The drawing and pixelOf share these two, so they agree exactly.
    const imageX = (cx) => Math.floor(st.panX + (cx + 0.5 - cw / 2) / st.zoom);
    const imageY = (cy) => Math.floor(st.panY + (cy + 0.5 - ch / 2) / st.zoom);
    function pixelOf(cx, cy) {
      const x = imageX(cx), y = imageY(cy);
      return x >= 0 && x < W && y >= 0 && y < H ? [x, y] : null;
    }
    function canvasOf(x, y) {
      return [Math.floor(cw / 2 + (x + 0.5 - st.panX) * st.zoom), Math.floor(ch / 2 + (y + 0.5 - st.panY) * st.zoom)];
    }

    // Nearest-neighbour resampling by hand, so single pixels stay sharp and
    // every device pixel shows exactly the image pixel pixelOf names.
    function drawPane(p, film) {
      const out = new Uint32Array(p.pixels.data.buffer), src = film && new Uint32Array(film.buffer);
      const cols = new Int32Array(cw);
      for (let cx = 0; cx < cw; cx++) {
        const x = imageX(cx);
        cols[cx] = x >= 0 && x < W ? x : -1;
      }
      for (let cy = 0, o = 0; cy < ch; cy++) {
        const y = imageY(cy);
        if (!src || y < 0 || y >= H) {
          out.fill(bg32, o, o + cw);
          o += cw;
          continue;
        }
        const row = y * W;
        for (let cx = 0; cx < cw; cx++, o++) out[o] = cols[cx] < 0 ? bg32 : src[row + cols[cx]];
      }
      p.ctx.putImageData(p.pixels, 0, 0);
    }
    // A pane re-renders its film only when what it shows changed, not on pan/zoom.
    function film(p, i, mode) {
      const key = `${i}/${st.frame}/${st.stops}/${mode}`;
      if (p.key !== key) {
        p.film = renderFilm(i, mode);
        p.key = key;
      }
      return p.film;
    }
    const shown = () => (st.showReference && ref !== null ? ref : st.image);

    function refresh() {
      const i = shown(), mode = st.mode, leftFilm = film(left, i, mode);
      drawPane(left, leftFilm);
      left.title.textContent = label(i) + (st.showReference ? ' (reference, r)' : '') +
        (mode === 'image' ? '' : ` — ${MODE_LABEL[mode]} against the reference`);
      left.caption.textContent = images[i].caption || '';
      if (right) {
        drawPane(right, film(right, ref, 'image'));
        right.title.textContent = label(ref) + (/reference/i.test(label(ref)) ? '' : ' (reference)');
        right.caption.textContent = images[ref].caption || '';
      }
      imageButtons.forEach((b, k) => {
        b.classList.toggle('pdv-selected', k === st.image);
        b.classList.toggle('pdv-shown', k === i && k !== st.image);
        b.setAttribute('aria-pressed', String(k === st.image));
      });
      modeButtons.forEach((b, k) => b.setAttribute('aria-pressed', String(MODES[k] === mode)));
      expo.input.value = st.stops;
      expo.out.textContent = fmtStops(st.stops);
      frameCtl.input.value = st.frame;
      frameCtl.out.textContent = `${st.frame} of 0–${F - 1}`;
      zoomInfo.textContent = `zoom ${fmt(st.zoom / dpr)}×`;
      updateLegend(ref === null ? 'no reference: error views are disabled'
        : leftFilm === null ? 'no FLIP map for this image' : '');
      updateReadout();
    }

    function updateLegend(message) {
      const mode = st.mode, s = E * 2 ** st.stops, table = COLORMAPS[mode];
      const stops = table.map((c, k) => `rgb(${c}) ${((100 * k) / (table.length - 1)).toFixed(1)}%`);
      ramp.style.background = `linear-gradient(to right, ${stops.join(', ')})`;
      legendTitle.textContent = {
        image: `exposure ${fmtStops(st.stops)}: linear value`,
        diff: 'mean RGB of (image − reference)',
        relmse: 'relMSE, log scale',
        flip: 'LDR-FLIP error',
      }[mode];
      // Image mode: 0, the value shown at the bar's middle (level 127.5), the value shown white.
      const labels = {
        image: ['0', fmt(0.214 / s), fmt(1 / s)],
        diff: ['−' + fmt(1 / s), '0', '+' + fmt(1 / s)],
        relmse: ['≤ 1e-4', '1e-2', '≥ 1'],
        flip: ['0', '0.5', '1'],
      }[mode];
      tickEls.forEach((t, k) => { t.textContent = labels[k]; });
      notice.textContent = message;
    }

    let pointer = null; // image pixel under the pointer
    function updateReadout() {
      if (!pointer) return;
      const [x, y] = pointer, f = st.frame, i = shown();
      const rgb = (k) => linear(k, f, x, y).map((v) => v.toPrecision(4)).join('  ');
      let s = `x ${x}, y ${y}, frame ${f}\n${label(i)}: ${rgb(i)}`;
      if (ref !== null) s += `\nreference: ${rgb(ref)}`;
      if (st.mode !== 'image') {
        const v = errorValue(st.mode, i, f, x, y);
        s += `\n${MODE_LABEL[st.mode]}: ${v === null ? 'none' : v.toPrecision(4)}`;
      }
      readout.textContent = s;
    }

    // --- input ------------------------------------------------------------------
    function devicePos(e) {
      const r = e.currentTarget.getBoundingClientRect();
      return [((e.clientX - r.left) * cw) / r.width, ((e.clientY - r.top) * ch) / r.height];
    }
    let drag = null;
    for (const p of [left, right]) {
      if (!p) continue;
      const c = p.canvas, end = () => {
        drag = null;
        c.classList.remove('pdv-dragging');
      };
      c.addEventListener('pointerdown', (e) => {
        drag = devicePos(e);
        c.setPointerCapture(e.pointerId);
        c.classList.add('pdv-dragging');
      });
      c.addEventListener('pointermove', guard((e) => {
        const [mx, my] = devicePos(e);
        pointer = pixelOf(Math.floor(mx), Math.floor(my)) || pointer;
        if (!drag) return updateReadout();
        st.panX -= (mx - drag[0]) / st.zoom;
        st.panY -= (my - drag[1]) / st.zoom;
        drag = [mx, my];
        clampPan();
        refresh();
      }));
      c.addEventListener('pointerup', end);
      c.addEventListener('pointercancel', end);
      c.addEventListener('wheel', guard((e) => {
        e.preventDefault();
        const [mx, my] = devicePos(e);
        const dy = e.deltaY * (e.deltaMode === 1 ? 33 : e.deltaMode === 2 ? 400 : 1);
        zoomAt(2 ** (-dy / 200), mx, my);
        refresh();
      }), { passive: false });
    }

    function select(i) {
      st.image = Math.min(Math.max(i, 0), images.length - 1);
      st.showReference = false;
    }
    function onKey(e) {
      if (e.ctrlKey || e.metaKey || e.altKey) return;
      const a = document.activeElement, tag = a ? a.tagName : '', k = e.key;
      if (tag === 'TEXTAREA' || tag === 'SELECT' || (a && a.isContentEditable)) return;
      // A focused slider keeps its own arrow keys; other keys still reach the viewer.
      if (tag === 'INPUT' && (a.type !== 'range' || k.startsWith('Arrow'))) return;
      if (/^[1-9]$/.test(k)) {
        if (+k > images.length) return;
        select(+k - 1);
      } else if (k === 'ArrowDown' || k === 'j') select(st.image + 1);
      else if (k === 'ArrowUp' || k === 'k') select(st.image - 1);
      else if (k === 'r') {
        if (ref === null) return;
        st.showReference = !st.showReference;
      } else if (k === 'e' || k === 'E') {
        st.stops = Math.min(Math.max(st.stops + (k === 'e' ? 1 : -1), -MAX_STOPS), MAX_STOPS);
      } else if (k === '0') st.stops = 0;
      else if (k === 'm') {
        if (ref === null) return;
        st.mode = MODES[(MODES.indexOf(st.mode) + 1) % MODES.length];
      } else if (k === 'f') fit();
      else if (k === '+' || k === '=') zoomAt(2, cw / 2, ch / 2);
      else if (k === '-') zoomAt(0.5, cw / 2, ch / 2);
      else if (k === ',' || k === '.') {
        if (F === 1) return;
        st.frame = (st.frame + (k === '.' ? 1 : F - 1)) % F;
      } else return;
      e.preventDefault();
      refresh();
    }
    document.addEventListener('keydown', guard(onKey));

    fit();
    refresh();
    if (!(document.body.dataset.status || '').startsWith('error')) document.body.dataset.status = 'ok';

    return {
      state: () => ({ ...st }),
      info: () => ({ width: W, height: H, frames: F, exposure: E, reference: ref, recommended: data.recommended, count: images.length }),
      linear,
      canvases: () => ({ left: left.canvas, right: right ? right.canvas : null }),
      colormap(mode, t) {
        const o = [0, 0, 0, 0];
        colour(COLORMAPS[mode], t, o, 0);
        return o.slice(0, 3);
      },
      errorValue,
      display: (v, stops) => level(v * E * 2 ** stops),
      pixelOf,
      canvasOf,
    };
  }

  window.PathdensityViewer = { mount, colormaps: COLORMAPS };
  // Mounts at once when the page's elements precede this script, else once the page is parsed.
  function autoMount(last) {
    const container = document.getElementById('viewer'), json = document.getElementById('viewer-data');
    if (!container || !json) {
      if (!last && document.readyState === 'loading') document.addEventListener('DOMContentLoaded', () => autoMount(true));
      return;
    }
    try {
      window.pathdensityViewer = mount(container, JSON.parse(json.textContent));
    } catch (err) {
      fail(err);
    }
  }
  autoMount(false);
})();
