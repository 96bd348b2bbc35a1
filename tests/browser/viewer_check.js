/* Browser check of the report's HDR viewer (src/report/viewer.js), injected at
 * the end of a generated report.html. It drives the viewer only through
 * keydown events on document and the window.pathdensityViewer test API, reads
 * the left canvas back with getImageData, and writes the outcome into
 * document.body.dataset.viewerTest: 'pass' or 'fail: <check>: <numbers>; ...'.
 * Checks that cannot apply (no reference, one frame) are named in
 * data-viewer-skipped. It never throws. */
(function () {
  'use strict';
  const failures = [];
  const skipped = [];
  const press = (key) =>
    document.dispatchEvent(new KeyboardEvent('keydown', { key, bubbles: true, cancelable: true }));
  // The display transform, written out again here so a bug in the viewer's own
  // copy (e.g. exposure applied twice) cannot hide behind it.
  const srgb = (u) => (u <= 0.0031308 ? 12.92 * u : 1.055 * Math.pow(u, 1 / 2.4) - 0.055);
  const expected = (x) => Math.round(255 * srgb(Math.min(Math.max(x, 0), 1)));
  const near = (a, b, tol) => b.every((x, k) => Math.abs(a[k] - x) <= tol); // compares b's channels
  const same = (a, b) => a[0] === b[0] && a[1] === b[1];

  function run(v) {
    const info = v.info(), W = info.width, H = info.height, F = info.frames, E = info.exposure, ref = info.reference;
    const canvas = v.canvases().left, cw = canvas.width, ch = canvas.height;
    const ctx = canvas.getContext('2d');
    const snap = () => ctx.getImageData(0, 0, cw, ch).data;
    const at = (d, c) => Array.from(d.subarray(4 * (c[1] * cw + c[0]), 4 * (c[1] * cw + c[0]) + 4));
    const inside = (c) => c[0] >= 0 && c[0] < cw && c[1] >= 0 && c[1] < ch;
    // Image pixel (x, y) is drawn at canvasOf(x, y) and that device pixel maps back to it.
    const drawnAt = (x, y) => {
      const c = v.canvasOf(x, y);
      return inside(c) && same(v.pixelOf(c[0], c[1]) || [-1, -1], [x, y]) ? c : null;
    };
    const finite = (a) => a.every(Number.isFinite);
    function select(i) {
      if (i < 9) press(String(i + 1));
      else {
        press('1');
        for (let k = 0; k < i; k++) press('ArrowDown');
      }
      const s = v.state();
      if (s.image !== i || s.showReference) throw new Error(`selecting image ${i} gave image ${s.image}`);
    }
    function mode(m) {
      for (let k = 0; k < 4 && v.state().mode !== m; k++) press('m');
      if (v.state().mode !== m) throw new Error(`m never reached mode ${m}, at ${v.state().mode}`);
    }
    function reset() {
      mode('image');
      press('0');
      press('f');
    }
    // Canvas pixels inside the image area that are not within ±1 of `rgb`.
    function countOff(data, rgb) {
      let n = 0, first = null;
      for (let cy = 0; cy < ch; cy++) {
        for (let cx = 0; cx < cw; cx++) {
          if (!v.pixelOf(cx, cy)) continue;
          const px = at(data, [cx, cy]);
          if (!near(px, rgb, 1)) {
            n++;
            first = first || `canvas ${cx},${cy} = ${px.slice(0, 3)}`;
          }
        }
      }
      return { n, first };
    }
    const methods = [];
    for (let i = 0; i < Math.min(9, info.count); i++) if (i !== ref) methods.push(i);

    step('1 two methods differ', () => {
      if (methods.length < 2) throw new Error(`only ${methods.length} non-reference image(s) on keys 1-9`);
      reset();
      select(methods[0]);
      const a = snap();
      select(methods[1]);
      const b = snap();
      if (a.every((x, k) => x === b[k])) throw new Error(`images ${methods[0]} and ${methods[1]} draw identical canvases`);
    });

    step('2 exposure +1 stop', () => {
      reset();
      const i = methods[methods.length > 1 ? 1 : 0];
      select(i);
      let hit = null;
      for (let y = 0; y < H && !hit; y++) {
        for (let x = 0; x < W && !hit; x++) {
          const lin = v.linear(i, 0, x, y), c = drawnAt(x, y);
          const ch3 = lin.findIndex((l) => l * E > 0.01 && l * E < 0.45);
          if (c && ch3 >= 0) hit = { x, y, c, k: ch3, l: lin[ch3] };
        }
      }
      if (!hit) throw new Error(`image ${i} has no pixel with v·E in (0.01, 0.45)`);
      const { x, y, c, k, l } = hit;
      const where = `image ${i} pixel ${x},${y} channel ${k} v ${l}`;
      const level = () => at(snap(), c)[k];
      const want0 = expected(l * E), want1 = expected(2 * l * E);
      const got0 = level();
      if (Math.abs(got0 - want0) > 1) throw new Error(`${where}: drawn ${got0}, expected ${want0} at 0 stops`);
      if (Math.abs(v.display(l, 0) - want0) > 1) throw new Error(`${where}: display(v, 0) = ${v.display(l, 0)}, expected ${want0}`);
      press('e');
      if (v.state().stops !== 1) throw new Error(`after e, stops = ${v.state().stops}`);
      const got1 = level();
      if (Math.abs(got1 - want1) > 1) throw new Error(`${where}: drawn ${got1}, expected ${want1} at +1 stop`);
      if (Math.abs(v.display(l, 1) - want1) > 1) throw new Error(`${where}: display(v, 1) = ${v.display(l, 1)}, expected ${want1}`);
      press('E');
      if (v.state().stops !== 0) throw new Error(`after E, stops = ${v.state().stops}`);
      press('e');
      press('e');
      press('0');
      const back = level();
      if (v.state().stops !== 0 || Math.abs(back - want0) > 1) throw new Error(`${where}: after 0, stops ${v.state().stops}, drawn ${back}, expected ${want0}`);
    });

    if (ref === null) skipped.push('3 and 4 (no reference)');
    else {
      step('3 reference against itself is zero', () => {
        reset();
        if (ref < 9) select(ref);
        else press('r');
        const centre = v.colormap('diff', 0.5);
        if (Math.max(...centre) - Math.min(...centre) > 16 || Math.min(...centre) < 200) throw new Error(`diverging centre ${centre} is not a light neutral`);
        const bad = [];
        for (const m of ['diff', 'relmse', 'flip']) {
          mode(m);
          const zero = m === 'diff' ? centre : v.colormap(m, 0);
          const off = countOff(snap(), zero);
          if (off.n) bad.push(`${m}: ${off.n} pixels off ${zero}, first ${off.first}`);
        }
        if (bad.length) throw new Error(bad.join(', '));
      });

      step('4 a noisy method is not zero', () => {
        reset();
        // The method whose mean RGB difference to the reference is largest (sampled).
        const stride = Math.max(1, Math.floor(Math.sqrt((W * H) / 20000)));
        let best = { d: 0 };
        for (const i of methods) {
          for (let y = 0; y < H; y += stride) {
            for (let x = 0; x < W; x += stride) {
              const a = v.linear(i, 0, x, y), r = v.linear(ref, 0, x, y);
              if (!finite(a) || !finite(r)) continue;
              const d = (a[0] - r[0] + a[1] - r[1] + a[2] - r[2]) / 3;
              if (Math.abs(d) > Math.abs(best.d) && drawnAt(x, y)) best = { i, x, y, d };
            }
          }
        }
        if (Math.abs(best.d * E) < 0.05) throw new Error(`no method differs visibly from the reference (max |d·E| ${Math.abs(best.d * E)})`);
        select(best.i);
        mode('diff');
        const data = snap(), zero = v.colormap('diff', 0.5), off = countOff(data, zero);
        if (!off.n) throw new Error(`image ${best.i}: signed difference is all zero`);
        const want = v.colormap('diff', (Math.min(Math.max(best.d * E, -1), 1) + 1) / 2);
        const got = at(data, drawnAt(best.x, best.y)).slice(0, 3);
        if (!near(got, want, 1)) throw new Error(`image ${best.i} pixel ${best.x},${best.y} d ${best.d}: drawn ${got}, expected ${want}`);
      });
    }

    if (F === 1) skipped.push('5 (one frame)');
    else {
      step('5 frames', () => {
        reset();
        select(methods[0]);
        const f0 = v.state().frame, a = snap();
        press('.');
        const f1 = v.state().frame, b = snap();
        if (f1 !== (f0 + 1) % F) throw new Error(`. moved frame ${f0} to ${f1}`);
        if (a.every((x, k) => x === b[k])) throw new Error(`frames ${f0} and ${f1} draw identical canvases`);
        press(',');
        if (v.state().frame !== f0) throw new Error(`, moved frame ${f1} to ${v.state().frame}, not ${f0}`);
      });
    }

    step('6 zoom', () => {
      reset();
      select(methods[0]);
      const z0 = v.state().zoom;
      press('+');
      const z1 = v.state().zoom;
      if (Math.abs(z1 - 2 * z0) > 1e-9 * z0) throw new Error(`+ took zoom ${z0} to ${z1}`);
      for (let k = 0; k < 12 && v.state().zoom < 4; k++) press('+');
      const z = v.state().zoom;
      if (z < 4) throw new Error(`zoom stuck at ${z}`);
      const data = snap(), p = v.pixelOf(cw >> 1, ch >> 1);
      if (!p) throw new Error('no image pixel at the canvas centre');
      // Every device pixel of the centre image pixel (and its right neighbour) has one colour.
      for (const [x, y] of [p, [Math.min(p[0] + 1, W - 1), p[1]]]) {
        const c = v.canvasOf(x, y), colour = at(data, c), r = Math.ceil(z) + 1;
        let n = 0;
        for (let cy = c[1] - r; cy <= c[1] + r; cy++) {
          for (let cx = c[0] - r; cx <= c[0] + r; cx++) {
            if (!inside([cx, cy]) || !same(v.pixelOf(cx, cy) || [-1, -1], [x, y])) continue;
            n++;
            const px = at(data, [cx, cy]);
            if (!near(px, colour, 0)) throw new Error(`zoom ${z}: pixel ${x},${y} drawn as ${colour} at ${c} but ${px} at ${cx},${cy}`);
          }
        }
        if (n < 4) throw new Error(`zoom ${z}: pixel ${x},${y} covers only ${n} device pixels`);
      }
      press('-');
      if (Math.abs(v.state().zoom - z / 2) > 1e-9 * z) throw new Error(`- took zoom ${z} to ${v.state().zoom}`);
      press('f');
      if (Math.abs(v.state().zoom - z0) > 1e-9 * z0) throw new Error(`f gave zoom ${v.state().zoom}, fit is ${z0}`);
    });

    if (ref === null) skipped.push('7 (no reference)');
    else {
      step('7 r flips to the reference and back', () => {
        reset();
        select(methods[0]);
        const a = snap();
        press('r');
        if (!v.state().showReference) throw new Error('r did not show the reference');
        const b = snap();
        press('r');
        if (v.state().showReference) throw new Error('a second r did not go back');
        const c = snap();
        if (!c.every((x, k) => x === a[k])) throw new Error('back from the reference, the canvas differs');
        if (a.every((x, k) => x === b[k])) throw new Error('the reference draws as the method');
        if (ref < 9) {
          select(ref);
          const d = snap();
          if (!d.every((x, k) => x === b[k])) throw new Error('r and selecting the reference draw differently');
        }
      });
    }

    step('8 pointer readout', () => {
      reset();
      const i = methods[0];
      select(i);
      const canvas = v.canvases().left, r = canvas.getBoundingClientRect();
      const x = W >> 1, y = H >> 1, c = drawnAt(x, y);
      if (!c) throw new Error(`pixel ${x},${y} is not drawn`);
      const client = (d) => [r.left + ((d[0] + 0.5) * r.width) / cw, r.top + ((d[1] + 0.5) * r.height) / ch];
      const [cx, cy] = client(c);
      const ev = (type, px, py) => canvas.dispatchEvent(new PointerEvent(type, { clientX: px, clientY: py, bubbles: true, pointerId: 1 }));
      ev('pointermove', cx, cy);
      const text = document.querySelector('.pdv-readout').textContent;
      const want = v.linear(i, 0, x, y).map((u) => u.toPrecision(4)).join('  ');
      if (!text.includes(`x ${x}, y ${y}`) || !text.includes(want)) throw new Error(`readout '${text}' lacks pixel ${x},${y} = ${want}`);
      if (ref !== null) {
        const wantRef = v.linear(ref, 0, x, y).map((u) => u.toPrecision(4)).join('  ');
        if (!text.includes(`reference: ${wantRef}`)) throw new Error(`readout '${text}' lacks the reference's ${wantRef}`);
      }
    });

    step('9 the exposure slider is the e key', () => {
      reset();
      select(methods[0]);
      press('e');
      const byKey = snap();
      press('0');
      const slider = [...document.querySelectorAll('input[type=range]')].find((el) => el.max > 1 && el.min < 0);
      if (!slider) throw new Error('no exposure slider');
      slider.value = 1;
      slider.dispatchEvent(new Event('input', { bubbles: true }));
      if (v.state().stops !== 1) throw new Error(`the slider at 1 gave ${v.state().stops} stops`);
      const bySlider = snap();
      if (!bySlider.every((x, k) => x === byKey[k])) throw new Error('the slider at +1 draws differently from e');
      press('0');
    });
  }

  function step(name, fn) {
    try {
      fn();
    } catch (err) {
      failures.push(`${name}: ${(err && err.message) || err}`);
    }
  }

  function finish() {
    const result = failures.length ? 'fail: ' + failures.join('; ') : 'pass';
    document.body.dataset.viewerTest = result;
    if (skipped.length) document.body.dataset.viewerSkipped = skipped.join('; ');
    console.log('viewer check: ' + result);
  }

  const started = Date.now();
  (function wait() {
    const status = document.body.dataset.status || '';
    if (status === 'ok' && window.pathdensityViewer) {
      step('run', () => run(window.pathdensityViewer));
      return finish();
    }
    if (status.startsWith('error') || Date.now() - started > 5000) {
      failures.push(`page status '${status}'${window.pathdensityViewer ? '' : ', no viewer'}`);
      return finish();
    }
    setTimeout(wait, 50);
  })();
})();
