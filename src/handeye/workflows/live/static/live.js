// handeye live: the page's script (no library). The server sends the whole state as JSON after every
// change and each frame as binary (4 bytes: the header's length, the JSON header, the JPEG); the page
// sends its actions as POST requests. window.__live keeps figures for the tests and the benchmark.
'use strict';
(function () {
  var $ = function (id) { return document.getElementById(id); };
  var live = window.__live = { frames: [], calibrations: {}, connected: false, state: null, errors: [] };
  var canvas = $('frame'), ctx = canvas.getContext('2d');
  var ws = null, lastFrameAt = 0, everConnected = false, pending = 0;
  var SVGNS = 'http://www.w3.org/2000/svg';

  function esc(s) { return String(s).replace(/[&<>"]/g, function (c) { return {'&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;'}[c]; }); }
  function fmt(v, d) { return v === null || v === undefined ? '—' : Number(v).toFixed(d); }
  function banner(text, level) {
    var b = $('banner');
    b.hidden = !text; b.textContent = text || ''; b.className = 'banner' + (level ? ' ' + level : '');
  }

  // -- the connection --------------------------------------------------------------------------------------
  function connect() {
    var proto = location.protocol === 'https:' ? 'wss://' : 'ws://';
    ws = new WebSocket(proto + location.host + '/ws');
    ws.binaryType = 'arraybuffer';
    live.ws = ws;
    ws.onopen = function () { live.connected = true; everConnected = true; banner(''); };
    ws.onmessage = function (ev) { if (typeof ev.data === 'string') render(JSON.parse(ev.data)); else drawFrame(ev.data); };
    ws.onclose = function () {
      live.connected = false;
      banner(everConnected ? 'The connection to the handeye live server was lost: reconnecting… (the views taken are in the ' +
             'session folder; restart the server with the same command if it stopped)' :
             'Cannot reach the handeye live server: retrying…');
      setTimeout(connect, 1000);
    };
  }

  // -- frames ----------------------------------------------------------------------------------------------
  function drawFrame(buf) {
    var n = new DataView(buf).getUint32(0, false);
    var head = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 4, n)));
    var blob = new Blob([new Uint8Array(buf, 4 + n)], { type: 'image/jpeg' });
    createImageBitmap(blob).then(function (img) {
      if (canvas.width !== head.width || canvas.height !== head.height) { canvas.width = head.width; canvas.height = head.height; }
      ctx.drawImage(img, 0, 0);
      overlay(head);
      lastFrameAt = Date.now();
      live.frames.push({ seq: head.seq, latency: Date.now() / 1000 - head.captured_at, found: head.found,
                         busy: !!(live.state && live.state.busy) });
      if (live.frames.length > 2000) live.frames.shift();
      var st = $('frame-status');
      if (head.found) {
        st.className = 'status good';
        st.textContent = 'target found: ' + head.n_found + ' of ' + head.n_total + ' points' +
          (head.missed.length ? ' (' + head.missed.length + ' missed, marked ×)' : '');
      } else {
        st.className = 'status bad';
        st.textContent = 'target not found in this image (the preview searches a smaller copy; a view taken is searched at full size)';
      }
    }).catch(function (e) { live.errors.push(String(e)); });
  }

  function overlay(h) {
    var r = Math.max(2, canvas.width / 220);
    ctx.lineWidth = Math.max(1.5, canvas.width / 400);
    ctx.strokeStyle = '#2ee66b';
    h.corners.forEach(function (p) { ctx.beginPath(); ctx.arc(p[0], p[1], r, 0, 2 * Math.PI); ctx.stroke(); });
    ctx.strokeStyle = '#ff3b30';
    h.missed.forEach(function (p) {
      ctx.beginPath(); ctx.moveTo(p[0] - r, p[1] - r); ctx.lineTo(p[0] + r, p[1] + r);
      ctx.moveTo(p[0] + r, p[1] - r); ctx.lineTo(p[0] - r, p[1] + r); ctx.stroke();
    });
    if (h.axes) {
      var o = h.axes[0], colours = ['#ff3b30', '#2ee66b', '#2f7bff'], names = ['x', 'y', 'z'];
      ctx.lineWidth = Math.max(2.5, canvas.width / 250);
      ctx.font = Math.round(canvas.width / 45) + 'px system-ui';
      for (var i = 1; i < 4; i++) {
        ctx.strokeStyle = colours[i - 1]; ctx.fillStyle = colours[i - 1];
        ctx.beginPath(); ctx.moveTo(o[0], o[1]); ctx.lineTo(h.axes[i][0], h.axes[i][1]); ctx.stroke();
        ctx.fillText(names[i - 1], h.axes[i][0] + 3, h.axes[i][1] - 3);
      }
    }
  }

  setInterval(function () {
    var st = $('frame-status');
    if (live.connected && lastFrameAt && Date.now() - lastFrameAt > 3000) {
      st.className = 'status bad';
      st.textContent = 'no image from the camera for ' + Math.round((Date.now() - lastFrameAt) / 1000) +
        ' s: the camera stopped sending (the views taken are kept)';
    }
  }, 500);

  // -- the state -------------------------------------------------------------------------------------------
  function render(s) {
    live.state = s;
    $('session').textContent = s.session;
    $('busy').textContent = s.busy ? s.busy + '…' : '';
    renderViews(s);
    renderCalibration(s);
    renderRobot(s);
    renderCoverage(s);
    renderDone(s);
    var log = $('log');
    log.innerHTML = s.messages.map(function (m) {
      return '<li class="' + m.level + '">' + new Date(m.t * 1000).toLocaleTimeString() + ' ' + esc(m.text) + '</li>';
    }).join('');
    log.scrollTop = log.scrollHeight;
    var problems = [];
    if (s.camera.error) problems.push('Camera: ' + s.camera.error);
    if (s.robot.error && s.robot.values === null && s.views.length) problems.push('Robot: ' + s.robot.error);
    else if (s.robot.error && s.views.length) problems.push('Robot: ' + s.robot.error);
    if (live.connected) banner(problems.join(' · '), 'warn');
    $('move').disabled = !(s.can_move && s.next_pose) || s.robot.moving;
    $('take').disabled = s.robot.moving;
  }

  function renderViews(s) {
    $('views-n').textContent = s.views.length + ' in the session' + (s.removed.length ? ', ' + s.removed.length + ' removed' : '');
    var box = $('views'), have = {}, skipped = {};
    ((s.calibration && s.calibration.skipped) || []).forEach(function (k) { skipped[k[0]] = k[1]; });
    Array.prototype.slice.call(box.children).forEach(function (f) { have[f.dataset.name] = f; });
    var names = s.views.map(function (v) { return v.name; });
    Object.keys(have).forEach(function (n) { if (names.indexOf(n) < 0) box.removeChild(have[n]); });
    s.views.forEach(function (v, i) {
      var f = have[v.name];
      if (!f) {
        f = document.createElement('figure');
        f.dataset.name = v.name;
        f.innerHTML = '<img alt="view ' + esc(v.name) + '" src="/views/' + encodeURIComponent(v.name) + '.jpg">' +
          '<figcaption><span></span><button type="button" class="remove" title="remove this view from the session">remove</button></figcaption>';
        f.querySelector('button').onclick = function () { act('remove', { name: v.name }, this); };
      }
      if (box.children[i] !== f) box.insertBefore(f, box.children[i] || null);
      f.className = skipped[v.name] ? 'outlier' : '';
      f.title = skipped[v.name] ? 'not used by the calibration: ' + skipped[v.name] : '';
      f.querySelector('span').textContent = v.name + ' · ' + fmt(v.rms, 2) + ' px';
    });
  }

  function renderCalibration(s) {
    var c = s.calibration, box = $('calib'), en = $('enough');
    $('calib-n').textContent = c ? 'from ' + c.n_views + ' views' : '';
    if (!c || c.error) {
      box.innerHTML = '<p class="muted">' + esc(c ? c.error : 'after ' + 3 + ' views') + '</p>';
      en.className = 'enough'; en.textContent = 'Not yet: take views at the planner\'s poses (or your own).';
    } else {
      var rows = [['translation (mm)', c.t_mm, 2], ['± std (mm)', c.std_mm, 3], ['rotation vector (deg)', c.rotvec_deg, 3],
                  ['± std (deg)', c.std_deg, 4]];
      var held = c.held_out || {};
      box.innerHTML = '<p><span class="verdict ' + esc(c.verdict) + '">' + esc(c.verdict) + '</span>: ' + esc(c.headline) + '</p>' +
        '<table><tr><th>' + esc(c.x_name) + '</th><th>x</th><th>y</th><th>z</th></tr>' +
        rows.map(function (r) {
          return '<tr><td>' + r[0] + '</td>' + (r[1] || [null, null, null]).map(function (v) { return '<td>' + fmt(v, r[2]) + '</td>'; }).join('') + '</tr>';
        }).join('') + '</table>' +
        '<p>held-out error: ' + (held.px !== null && held.px !== undefined ? fmt(held.px, 2) + ' px, ' : '') + fmt(held.mm, 2) +
        ' mm at the target (views predicted by fits on the others); estimator: ' + esc(c.estimator) + '</p>' +
        (c.advice.length ? '<p class="muted">' + c.advice.map(esc).join('<br>') + '</p>' : '');
      en.className = 'enough' + (c.enough ? ' yes' : '');
      en.textContent = (c.enough ? 'Enough. ' : '') + c.enough_text.charAt(0).toUpperCase() + c.enough_text.slice(1);
    }
    if (c && c.views) {  // when each view's calibration (or why there is none yet) was first shown
      var now = Date.now() / 1000;
      s.views.forEach(function (v) {
        if (c.views.indexOf(v.name) >= 0 && !(v.name in live.calibrations)) live.calibrations[v.name] = now - v.taken_at;
      });
    }
    plot($('plot-deg'), s.history, 'std_deg', s.target_std[0], 'rotation std (deg)');
    plot($('plot-mm'), s.history, 'std_mm', s.target_std[1], 'translation std (mm)');
  }

  function el(name, attrs, text) {
    var e = document.createElementNS(SVGNS, name);
    Object.keys(attrs).forEach(function (k) { e.setAttribute(k, attrs[k]); });
    if (text !== undefined) e.textContent = text;
    return e;
  }

  // the std against the number of views, on a log scale, with the target dashed
  function plot(svg, history, key, target, label) {
    while (svg.firstChild) svg.removeChild(svg.firstChild);
    var W = +svg.getAttribute('width'), H = +svg.getAttribute('height'), L = 40, B = 18, T = 14;
    svg.appendChild(el('text', { x: 2, y: 10 }, label));
    var pts = history.filter(function (h) { return h[key] > 0 && isFinite(h[key]); });
    if (!pts.length) return;
    var ys = pts.map(function (h) { return h[key]; }).concat([target]);
    var lo = Math.log10(Math.min.apply(null, ys)) - 0.1, hi = Math.log10(Math.max.apply(null, ys)) + 0.1;
    var n0 = pts[0].n, n1 = Math.max(pts[pts.length - 1].n, n0 + 1);
    var X = function (n) { return L + (W - L - 6) * (n - n0) / (n1 - n0); };
    var Y = function (v) { return T + (H - T - B) * (hi - Math.log10(v)) / (hi - lo); };
    svg.appendChild(el('line', { x1: L, x2: W - 4, y1: Y(target), y2: Y(target), stroke: '#1b7f3b', 'stroke-dasharray': '4 3' }));
    svg.appendChild(el('text', { x: L + 2, y: Y(target) + 11, fill: '#1b7f3b' }, 'target ' + target));
    svg.appendChild(el('polyline', { fill: 'none', stroke: '#1b5fbf', 'stroke-width': 2,
      points: pts.map(function (h) { return X(h.n) + ',' + Y(h[key]); }).join(' ') }));
    pts.forEach(function (h) { svg.appendChild(el('circle', { cx: X(h.n), cy: Y(h[key]), r: 2.5, fill: '#1b5fbf' })); });
    [hi - 0.1, lo + 0.1].forEach(function (e) {
      var v = Math.pow(10, e);
      svg.appendChild(el('text', { x: L - 3, y: Y(v) + 3, 'text-anchor': 'end' }, v < 0.1 ? v.toPrecision(1) : v.toPrecision(2)));
    });
    svg.appendChild(el('text', { x: L, y: H - 4 }, n0 + ' views'));
    svg.appendChild(el('text', { x: W - 4, y: H - 4, 'text-anchor': 'end' }, n1));
  }

  function poseTable(p, values) {
    return '<table><tr>' + p.columns.map(function (c) { return '<th>' + esc(c) + '</th>'; }).join('') + '</tr><tr>' +
      values.map(function (v) { return '<td>' + fmt(v, 4) + '</td>'; }).join('') + '</tr></table>' +
      '<p class="muted">' + esc(p.format) + ', ' + esc(p.units.join(', ')) + '</p>';
  }

  function renderRobot(s) {
    var r = s.robot;
    $('robot').innerHTML = (r.values ? poseTable(r, r.values) : '') + (r.moving ? '<p>moving…</p>' : '') +
      (r.error ? '<p class="status bad">' + esc(r.error) + '</p>' : '');
  }

  function renderCoverage(s) {
    var svg = $('axes'), c = s.coverage;
    while (svg.firstChild) svg.removeChild(svg.firstChild);
    var R = 90, cx = 100, cy = 100;
    svg.appendChild(el('circle', { cx: cx, cy: cy, r: R, fill: '#f6f7f8', stroke: '#9aa3ab' }));
    svg.appendChild(el('text', { x: cx + R - 8, y: cy - 3 }, 'x'));
    svg.appendChild(el('text', { x: cx + 3, y: cy - R + 12 }, 'y'));
    if (c) {
      c.axes.forEach(function (a, i) {
        var rho = Math.sqrt(Math.max(0, 1 - a[2])), xy = Math.hypot(a[0], a[1]) || 1;  // equal-area, upper half
        var deg = c.angles_deg[i];
        svg.appendChild(el('circle', { cx: cx + R * rho * a[0] / xy, cy: cy - R * rho * a[1] / xy, r: 1.5 + Math.min(deg, 90) / 20,
          fill: 'hsl(' + Math.round(Math.min(deg, 90) * 1.3) + ',70%,45%)', 'fill-opacity': 0.7 }));
      });
    }
    $('coverage').textContent = c ? c.summary + '. Each dot: the axis of one rotation between two views, ' +
      'seen along the flange\'s z axis (centre: about z; the rim: axes in the x-y plane); larger and greener: a larger angle.' :
      'after 2 views';
    var p = s.next_pose;
    $('next').innerHTML = p ? poseTable(p, p.values) + (p.can_move ? '' : '<p>Jog the robot to this pose, then take the view.</p>')
      : '<p class="muted">' + (s.planning ? 'choosing the next pose after the last view…' : 'none: no candidate view left') + '</p>';
  }

  function renderDone(s) {
    var d = s.finished, box = $('done');
    box.hidden = !d;
    if (!d) return;
    box.innerHTML = '<strong>Written.</strong> The calibration of ' + d.n_views + ' views: ' +
      d.files.map(function (f) { return '<a href="/results/' + encodeURIComponent(f) + '" target="_blank">' + esc(f) + '</a>'; }).join(', ') +
      '<br>in <span class="mono">' + esc(d.folder) + '</span><br>The session folder: <span class="mono">' + esc(d.session) + '</span>';
  }

  // -- actions ---------------------------------------------------------------------------------------------
  function act(action, body, button) {
    if (button) button.disabled = true;
    pending++;
    var answer = $('answer');
    answer.className = 'answer'; answer.textContent = action + '…';
    return fetch('/api/' + action, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body || {}) })
      .then(function (r) { return r.json(); })
      .then(function (a) { answer.className = 'answer' + (a.ok ? '' : ' bad'); answer.textContent = a.message; return a; })
      .catch(function (e) {
        answer.className = 'answer bad';
        answer.textContent = action + ': no answer from the server (' + e + '); the views taken are in the session folder';
      })
      .then(function (a) { pending--; if (button) button.disabled = false; return a; });
  }
  $('take').onclick = function () { live.lastClick = Date.now(); act('take', {}, this); };
  $('move').onclick = function () { act('move', {}, this); };
  $('finish').onclick = function () { act('finish', {}, this); };
  live.pending = function () { return pending; };
  connect();
})();
