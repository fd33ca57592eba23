/* SPDX-License-Identifier: MIT */
// ctrlbus dashboard page: plain JavaScript, no build step, no network access beyond its own server.
// It renders the snapshots the server pushes (schema: docs/dashboard.md) and sends control
// messages (velocity, estop, release, go_home, external_command) over the same WebSocket.
"use strict";

(() => {
  const $ = (id) => document.getElementById(id);
  const token = new URLSearchParams(location.search).get("token");

  const TELEOP_REPEAT_MS = 100; // the server zeroes teleop that is not repeated within its hold time
  const RECONNECT_MS = 1000;
  const DEFAULT_RADIUS_MM = 150;
  const BEACON_COLOURS = { left: "255,160,64", main: "255,230,80", right: "200,120,255" };
  const LEVELS = { 1: "warning", 2: "error", 4: "fatal" };
  const COMPONENTS = { 0: "user", 1: "system", 2: "power", 3: "motion", 4: "sensor" };

  let ws = null;
  let hello = null;
  let snap = null;
  let drawPending = false;
  let lastEventSeq = -1;
  let view = null; // {cx, cy, span} in mm; grows to fit, reset by "fit"
  const held = new Set(); // drive directions currently pressed: forward, backward, left, right
  let repeatTimer = null;
  let sentMotion = false;

  // ---------------------------------------------------------------- connection

  function connect() {
    const url = new URL("/ws", location.href);
    url.protocol = location.protocol === "https:" ? "wss:" : "ws:";
    url.search = "";
    if (token) url.searchParams.set("token", token);
    setWsState("connecting");
    ws = new WebSocket(url);
    ws.onopen = () => setWsState("open");
    ws.onmessage = (event) => {
      let message;
      try {
        message = JSON.parse(event.data);
      } catch (err) {
        return;
      }
      handle(message);
    };
    ws.onclose = () => {
      ws = null;
      setWsState("closed");
      setTimeout(connect, RECONNECT_MS);
    };
  }

  function setWsState(state) {
    const el = $("ws-state");
    el.dataset.value = state;
    el.textContent = "page: " + state;
    el.className = "pill " + (state === "open" ? "good" : state === "connecting" ? "warn" : "bad");
  }

  function send(message) {
    if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(message));
  }

  function handle(message) {
    if (message.type === "hello") {
      hello = message;
      buildExternalButtons();
    } else if (message.type === "snapshot") {
      snap = message.data;
      renderPanels(snap);
      if (!drawPending) {
        drawPending = true;
        requestAnimationFrame(() => {
          drawPending = false;
          drawMap();
        });
      }
    } else if (message.type === "error") {
      showReply("refused: " + message.error, true);
    } else if (message.type === "ack" && message.for !== "velocity") {
      showReply(message.for + (message.name ? " " + message.name : "") + ": sent", false);
    }
  }

  function showReply(text, bad) {
    const el = $("reply");
    el.textContent = text;
    el.className = "reply" + (bad ? " bad" : "");
  }

  // ---------------------------------------------------------------- panels

  function setValue(id, value, text) {
    const el = $(id);
    el.dataset.value = value === null || value === undefined ? "" : String(value);
    el.textContent = text === undefined ? (value === null || value === undefined ? "–" : String(value)) : text;
  }

  function fixed(value, digits) {
    return value === null || value === undefined ? "–" : Number(value).toFixed(digits);
  }

  function lamp(id, on) {
    $(id).classList.toggle("on", Boolean(on));
  }

  function hex(code, width) {
    return "0x" + (code >>> 0).toString(16).toUpperCase().padStart(width, "0");
  }

  function renderPanels(s) {
    const conn = s.link.connection;
    const pill = $("conn-state");
    pill.dataset.value = conn.state;
    pill.textContent = "base: " + conn.state;
    pill.className = "pill " + ({ connected: "good", disconnected: "bad" }[conn.state] || "warn");
    $("base-info").textContent = s.base
      ? `${s.base.model || "(no model)"} · firmware ${s.base.firmware_version} · ${s.base.shape} r ${fixed(s.base.radius_mm, 0)} mm · ${s.base.config_source}`
      : "no base configuration yet";
    // 0x21 "not supported" is the base's ordinary answer when it has no blob: shown here, apart
    // from the errors; the other states say why the Core is not (yet) using a blob.
    const blobNotes = {
      not_supported: " (0x21 not supported: fallback, not an error)",
      unusable: " (0x21 blob unusable)",
      pending: " (0x21 blob not received intact yet: asked again)",
    };
    if (s.base && s.base.blob && blobNotes[s.base.blob]) $("base-info").textContent += blobNotes[s.base.blob];
    let clock = "Core " + fixed(s.time_s, 1) + " s";
    if (s.sim) clock += ` · simulated ${fixed(s.sim.time_s, 1)} s` + (s.sim.speed === undefined ? "" : ` (×${fixed(s.sim.speed, 1)})`);
    $("clock").textContent = clock;

    for (const el of document.querySelectorAll(".sim-only")) el.hidden = !s.sim;

    // pose
    setValue("pose-x", s.pose.x_mm, fixed(s.pose.x_mm, 0));
    setValue("pose-y", s.pose.y_mm, fixed(s.pose.y_mm, 0));
    setValue("pose-theta", s.pose.theta_deg, fixed(s.pose.theta_deg, 1));
    if (s.sim) {
      const t = s.sim.pose;
      const d = drToRoom(s.pose, s.sim.odometry_origin);
      $("truth-pose").textContent = `${fixed(t.x_mm, 0)}, ${fixed(t.y_mm, 0)} mm, ${fixed(t.theta_deg, 1)}°`;
      const dist = Math.hypot(d.x_mm - t.x_mm, d.y_mm - t.y_mm);
      $("drift").textContent = `${fixed(dist, 0)} mm, ${fixed(angleDiff(d.theta_deg, t.theta_deg), 1)}°` + (s.sim.motion.held_by ? ` · held by ${s.sim.motion.held_by}` : "");
    }

    // command
    setValue("cmd-vx", s.command.vx_mps, fixed(s.command.vx_mps, 3) + " m/s");
    setValue("cmd-omega", s.command.omega_radps, fixed(s.command.omega_radps, 3) + " rad/s");
    setValue("cmd-mode", s.command.mode, s.command.mode + (s.command.activity ? ": " + s.command.activity : ""));
    $("limits").textContent = `±${fixed(s.limits.vx_mps, 2)} m/s, ±${fixed(s.limits.omega_radps, 2)} rad/s`;
    $("estop-banner").hidden = !s.command.estop;
    $("estop").classList.toggle("active", s.command.estop);
    updateSpeedLabel();
    $("external-box").hidden = !(s.sim && hello && hello.external_commands.length);

    // battery, dock, contacts
    const b = s.battery;
    setValue("battery-percent", b.percent, b.percent === null ? "–" : b.percent + " %");
    const bar = $("battery-bar");
    bar.style.width = (b.percent || 0) + "%";
    bar.className = b.percent !== null && b.percent < 10 ? "critical" : b.percent !== null && b.percent < 30 ? "low" : "";
    lamp("lamp-charging", b.charging);
    lamp("lamp-dc", b.dc_connected);
    lamp("lamp-dock", b.on_dock);
    const rows = $("beacons").rows;
    for (let probe = 0; probe < 3; probe++) {
      const bits = s.charger && probe < s.charger.probes.length ? s.charger.probes[probe] : 0;
      for (let beacon = 0; beacon < 3; beacon++) rows[probe + 1].cells[beacon + 1].classList.toggle("on", Boolean(bits & (1 << beacon)));
    }
    renderLamps("bumper-lamps", s.bumpers.map((x, i) => ["bumper " + i + " (bit " + x.bit + ")", x.pressed]));
    renderLamps("cliff-lamps", s.cliffs.map((x, i) => ["cliff " + i + " (bit " + x.bit + ")", x.triggered]));
    lamp("lamp-stall", s.motion.stall);
    lamp("lamp-traction", s.motion.traction_lost);

    // health
    lamp("lamp-warning", s.health.warning);
    lamp("lamp-error", s.health.error);
    lamp("lamp-fatal", s.health.fatal);
    const body = $("health-errors").tBodies[0];
    const key = JSON.stringify(s.health.errors);
    if (body.dataset.key !== key) {
      body.dataset.key = key;
      body.replaceChildren(
        ...s.health.errors.map((e) => {
          const level = (e.code >>> 24) & 0xff;
          const component = (e.code >>> 16) & 0xff;
          return row([hex(e.code, 8), LEVELS[level] || "level " + level, COMPONENTS[component] || "component " + component, e.message], "level-" + level);
        })
      );
    }

    // link
    const l = s.link;
    setValue("link-state", conn.state);
    $("link-port").textContent = conn.port;
    setValue("link-requests", l.requests);
    setValue("link-rps", l.requests_per_s, fixed(l.requests_per_s, 1));
    setValue("link-p50", l.latency_p50_ms, fixed(l.latency_p50_ms, 1));
    setValue("link-p99", l.latency_p99_ms, fixed(l.latency_p99_ms, 1));
    const codes = Object.entries(l.errors_by_code).sort();
    $("link-errors").textContent = codes.length ? codes.map(([c, n]) => `${c}: ${n}`).join(", ") : "none";
    setValue("link-checksum", l.checksum_failures);
    setValue("link-resyncs", l.resyncs);
    setValue("link-timeouts", l.timeouts);
    setValue("link-retries", l.retries);
    setValue("link-lost", l.lost_requests);
    setValue("link-superseded", l.superseded);
    setValue("link-watchdog", l.watchdog_trips);
    setValue("link-connects", conn.connects);

    // sensors
    const sensors = $("sensors").tBodies[0];
    if (sensors.rows.length !== s.sensors.length) {
      sensors.replaceChildren(...s.sensors.map((x, i) => row([String(i), "", ""])));
    }
    s.sensors.forEach((x, i) => {
      const cells = sensors.rows[i].cells;
      cells[1].textContent = `${fixed(x.x_mm, 0)}, ${fixed(x.y_mm, 0)}, ${fixed(x.angle_deg, 0)}°`;
      cells[2].textContent = x.distance_mm === null ? "–" : x.distance_mm === 0 ? "0 (no echo)" : fixed(x.distance_mm, 0) + " mm";
    });

    // readings of channels the configuration in use does not list: a real Core ignores them
    const ignoredRows = s.ignored_sensors || [];
    const warnings = s.warnings || [];
    $("sensor-warning").hidden = warnings.length === 0;
    $("sensor-warning").textContent = warnings.join(" ");
    const ignoredTable = $("ignored-sensors");
    ignoredTable.hidden = ignoredRows.length === 0;
    ignoredTable.tBodies[0].replaceChildren(...ignoredRows.map((x) => row([
      String(x.slot),
      x.mount ? `${fixed(x.mount.x_mm, 0)}, ${fixed(x.mount.y_mm, 0)}, ${fixed(x.mount.angle_deg, 0)}° (${x.mount_source})` : "unknown",
      fixed(x.distance_mm, 0) + " mm (ignored)",
    ])));

    renderEvents(s.events);
  }

  function row(texts, className) {
    const tr = document.createElement("tr");
    if (className) tr.className = className;
    for (const text of texts) {
      const td = document.createElement("td");
      td.textContent = text;
      tr.appendChild(td);
    }
    return tr;
  }

  function renderLamps(id, items) {
    const box = $(id);
    if (box.children.length !== items.length) {
      box.replaceChildren(
        ...items.map(([label]) => {
          const span = document.createElement("span");
          span.className = "lamp bad";
          span.textContent = label;
          return span;
        })
      );
    }
    items.forEach(([, on], i) => box.children[i].classList.toggle("on", Boolean(on)));
  }

  function renderEvents(events) {
    const list = $("events");
    if (events.length && events[events.length - 1].seq < lastEventSeq) {
      list.replaceChildren(); // a new Core session: its numbering starts again
      lastEventSeq = -1;
    }
    for (const e of events) {
      if (e.seq <= lastEventSeq) continue;
      lastEventSeq = e.seq;
      const li = document.createElement("li");
      const t = document.createElement("span");
      t.className = "t";
      t.textContent = Number(e.t_s).toFixed(2);
      const dir = document.createElement("span");
      dir.className = "dir " + e.direction;
      dir.textContent = e.direction;
      li.append(t, dir, document.createTextNode(e.text));
      list.prepend(li);
    }
    while (list.children.length > 300) list.lastElementChild.remove();
  }

  function buildExternalButtons() {
    const box = $("external-commands");
    box.replaceChildren(
      ...hello.external_commands.map((cmd) => {
        const button = document.createElement("button");
        button.type = "button";
        button.textContent = cmd.name;
        button.title = hex(cmd.code, 2);
        button.dataset.testid = "ext-" + cmd.name;
        button.addEventListener("click", () => send({ type: "external_command", code: cmd.code }));
        return button;
      })
    );
  }

  // ---------------------------------------------------------------- control

  function speedFraction() {
    return Number($("speed").value) / 100;
  }

  function updateSpeedLabel() {
    const f = speedFraction();
    const lim = snap ? snap.limits : { vx_mps: 0, omega_radps: 0 };
    $("speed-value").textContent = `${Math.round(f * 100)} % (${(lim.vx_mps * f).toFixed(2)} m/s, ${(lim.omega_radps * f).toFixed(2)} rad/s)`;
  }

  function desiredVelocity() {
    const f = speedFraction();
    const lim = snap ? snap.limits : { vx_mps: 0, omega_radps: 0 };
    let vx = 0;
    let omega = 0;
    if (held.has("forward")) vx += lim.vx_mps * f;
    if (held.has("backward")) vx -= lim.vx_mps * f;
    if (held.has("left")) omega += lim.omega_radps * f;
    if (held.has("right")) omega -= lim.omega_radps * f;
    return [vx, omega];
  }

  // Sends the velocity now, and keeps repeating it while anything is held.
  function drive() {
    if (held.size) {
      const [vx, omega] = desiredVelocity();
      send({ type: "velocity", vx_mps: vx, omega_radps: omega });
      sentMotion = true;
      if (repeatTimer === null) repeatTimer = setInterval(drive, TELEOP_REPEAT_MS);
    } else {
      if (repeatTimer !== null) {
        clearInterval(repeatTimer);
        repeatTimer = null;
      }
      if (sentMotion) {
        send({ type: "velocity", vx_mps: 0, omega_radps: 0 });
        sentMotion = false;
      }
    }
    for (const button of document.querySelectorAll("button.drive")) button.classList.toggle("active", held.has(button.dataset.drive));
  }

  function press(direction) {
    if (!held.has(direction)) {
      held.add(direction);
      drive();
    }
  }

  function release(direction) {
    if (held.delete(direction)) drive();
  }

  const KEYS = { ArrowUp: "forward", ArrowDown: "backward", ArrowLeft: "left", ArrowRight: "right" };

  window.addEventListener(
    "keydown",
    (event) => {
      if (event.ctrlKey || event.metaKey || event.altKey) return;
      const direction = KEYS[event.key];
      if (direction) {
        event.preventDefault(); // arrows drive the robot, not the slider or the page scroll
        press(direction);
      } else if (event.key === " ") {
        event.preventDefault();
        emergencyStop();
      } else if (event.key === "+" || event.key === "=") {
        $("speed").stepUp();
        updateSpeedLabel();
      } else if (event.key === "-") {
        $("speed").stepDown();
        updateSpeedLabel();
      }
    },
    true
  );
  window.addEventListener(
    "keyup",
    (event) => {
      const direction = KEYS[event.key];
      if (direction) {
        event.preventDefault();
        release(direction);
      }
    },
    true
  );
  // A key released while the page had no focus never sends keyup: stop rather than run on.
  window.addEventListener("blur", () => {
    held.clear();
    drive();
  });

  for (const button of document.querySelectorAll("button.drive")) {
    const direction = button.dataset.drive;
    button.addEventListener("pointerdown", (event) => {
      button.setPointerCapture(event.pointerId);
      press(direction);
    });
    for (const name of ["pointerup", "pointercancel", "lostpointercapture"]) button.addEventListener(name, () => release(direction));
  }

  function emergencyStop() {
    send({ type: "estop" });
  }

  $("teleop-stop").addEventListener("click", () => {
    held.clear();
    drive();
    send({ type: "velocity", vx_mps: 0, omega_radps: 0 });
  });
  $("estop").addEventListener("click", emergencyStop);
  $("release").addEventListener("click", () => send({ type: "release" }));
  $("go-home").addEventListener("click", () => send({ type: "go_home" }));
  $("speed").addEventListener("input", () => {
    updateSpeedLabel();
    if (held.size) drive();
  });
  $("map-fit").addEventListener("click", () => {
    view = null;
    drawMap();
  });

  // ---------------------------------------------------------------- map

  function angleDiff(a, b) {
    return ((((a - b) % 360) + 540) % 360) - 180;
  }

  // The Core's dead-reckoned frame starts at the simulator's odometry origin.
  function drToRoom(pose, origin) {
    if (!origin) return pose;
    const r = (origin.theta_deg * Math.PI) / 180;
    const c = Math.cos(r);
    const s = Math.sin(r);
    return { x_mm: origin.x_mm + c * pose.x_mm - s * pose.y_mm, y_mm: origin.y_mm + s * pose.x_mm + c * pose.y_mm, theta_deg: origin.theta_deg + pose.theta_deg };
  }

  function pointToRoom([x, y], origin) {
    const p = drToRoom({ x_mm: x, y_mm: y, theta_deg: 0 }, origin);
    return [p.x_mm, p.y_mm];
  }

  function bounds(points) {
    let minX = Infinity, minY = Infinity, maxX = -Infinity, maxY = -Infinity;
    for (const [x, y] of points) {
      minX = Math.min(minX, x);
      minY = Math.min(minY, y);
      maxX = Math.max(maxX, x);
      maxY = Math.max(maxY, y);
    }
    return { minX, minY, maxX, maxY };
  }

  function wanted(s, drPose) {
    const pts = [];
    if (s.sim) {
      for (const wall of s.sim.room.walls) for (const p of wall.points) pts.push(p);
      pts.push([s.sim.pose.x_mm, s.sim.pose.y_mm]);
    }
    const margin = 1000;
    pts.push([drPose.x_mm - margin, drPose.y_mm - margin], [drPose.x_mm + margin, drPose.y_mm + margin]);
    if (!s.sim) {
      for (const p of s.trail) pts.push(p);
      // what the sensors see, so that the rays fit in the picture
      for (const sensor of s.sensors) {
        if (!sensor.distance_mm) continue;
        const m = mountToRoom(sensor, drPose);
        pts.push([m.x + Math.cos(m.angle) * sensor.distance_mm, m.y + Math.sin(m.angle) * sensor.distance_mm]);
      }
    }
    const b = bounds(pts);
    return { cx: (b.minX + b.maxX) / 2, cy: (b.minY + b.maxY) / 2, span: Math.max(b.maxX - b.minX, b.maxY - b.minY, 2000) * 1.08 };
  }

  function drawMap() {
    const canvas = $("map");
    const dpr = window.devicePixelRatio || 1;
    const width = Math.max(200, Math.round(canvas.clientWidth * dpr));
    const height = Math.max(150, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== width || canvas.height !== height) {
      canvas.width = width;
      canvas.height = height;
    }
    const ctx = canvas.getContext("2d");
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = "#0e1014";
    ctx.fillRect(0, 0, width, height);
    const s = snap;
    if (!s) return;
    const origin = s.sim ? s.sim.odometry_origin : null;
    const dr = drToRoom(s.pose, origin);

    const want = wanted(s, dr);
    if ($("map-follow").checked) {
      view = { cx: dr.x_mm, cy: dr.y_mm, span: view ? view.span : 4000 };
    } else if (!view) {
      view = want;
    } else {
      // Grow (never shrink by itself) so the picture does not jitter as the robot moves.
      const half = view.span / 2;
      const b = bounds([[view.cx - half, view.cy - half], [view.cx + half, view.cy + half], [want.cx - want.span / 2, want.cy - want.span / 2], [want.cx + want.span / 2, want.cy + want.span / 2]]);
      view = { cx: (b.minX + b.maxX) / 2, cy: (b.minY + b.maxY) / 2, span: Math.max(b.maxX - b.minX, b.maxY - b.minY) };
    }
    const scale = Math.min(width, height) / view.span; // px per mm
    const X = (x) => width / 2 + (x - view.cx) * scale;
    const Y = (y) => height / 2 - (y - view.cy) * scale;
    const px = dpr;

    drawGrid(ctx, width, height, scale, X, Y, px);

    if (s.sim) drawSimulator(ctx, s.sim, X, Y, scale, px);

    // the Core's view: trail, robot, distance-sensor rays, bumpers
    drawTrail(ctx, s.trail.map((p) => pointToRoom(p, origin)), X, Y, "rgba(77,163,255,0.8)", px);
    const shape = s.base ? s.base.shape : "circle";
    const radius = s.base ? s.base.radius_mm : s.sim ? s.sim.robot.radius_mm : DEFAULT_RADIUS_MM;
    drawSensorRays(ctx, s.sensors, dr, X, Y, px);
    drawRobot(ctx, dr, shape, radius, X, Y, scale, "#4da3ff", px);
    drawBumpers(ctx, s.bumpers, dr, radius, X, Y, scale, px);
  }

  // The simulator's ground truth: room, cliffs, dock and beacon cones, true robot and its sensors.
  function drawSimulator(ctx, sim, X, Y, scale, px) {
    const room = sim.room;
    const path = (points, closed) => {
      ctx.beginPath();
      points.forEach(([x, y], i) => (i ? ctx.lineTo(X(x), Y(y)) : ctx.moveTo(X(x), Y(y))));
      if (closed) ctx.closePath();
    };
    ctx.fillStyle = "rgba(255,90,90,0.16)";
    ctx.strokeStyle = "rgba(255,90,90,0.6)";
    ctx.lineWidth = px;
    for (const cliff of room.cliffs) {
      if (!cliff.points.length) continue;
      path(cliff.points, true);
      ctx.fill();
      ctx.stroke();
      const [x, y] = cliff.points[0];
      ctx.fillStyle = "rgba(255,120,120,0.8)";
      ctx.font = `${11 * px}px system-ui, sans-serif`;
      ctx.fillText("cliff: " + cliff.name, X(x) + 4 * px, Y(y) - 4 * px);
      ctx.fillStyle = "rgba(255,90,90,0.16)";
    }
    if (room.dock) {
      for (const beacon of room.dock.beacons) {
        const a = (beacon.heading_deg * Math.PI) / 180;
        const h = (beacon.cone_deg * Math.PI) / 360;
        const colour = BEACON_COLOURS[beacon.name] || "180,180,180";
        ctx.beginPath();
        ctx.moveTo(X(beacon.x_mm), Y(beacon.y_mm));
        ctx.arc(X(beacon.x_mm), Y(beacon.y_mm), beacon.range_mm * scale, -(a + h), -(a - h));
        ctx.closePath();
        ctx.fillStyle = `rgba(${colour},0.08)`;
        ctx.fill();
        ctx.strokeStyle = `rgba(${colour},0.35)`;
        ctx.stroke();
      }
      drawDock(ctx, room.dock, X, Y, scale, px);
    }
    ctx.strokeStyle = "#c9d1dc";
    ctx.lineWidth = 3 * px;
    for (const wall of room.walls) {
      path(wall.points, wall.closed);
      ctx.stroke();
    }
    // distance sensors as the simulator casts them (dashed), from the true pose
    ctx.lineWidth = px;
    ctx.setLineDash([4 * px, 4 * px]);
    ctx.strokeStyle = "rgba(76,211,122,0.45)";
    for (const sensor of sim.distance_sensors) {
      if (sensor.hit_mm === null) continue;
      const a = (sensor.heading_deg * Math.PI) / 180;
      ctx.beginPath();
      ctx.moveTo(X(sensor.x_mm), Y(sensor.y_mm));
      ctx.lineTo(X(sensor.x_mm + Math.cos(a) * sensor.hit_mm), Y(sensor.y_mm + Math.sin(a) * sensor.hit_mm));
      ctx.stroke();
    }
    ctx.setLineDash([]);
    drawTrail(ctx, sim.trail, X, Y, "rgba(76,211,122,0.7)", px);
    drawRobot(ctx, sim.pose, "circle", sim.robot.radius_mm, X, Y, scale, "#4cd37a", px);
    const r = Math.max(sim.robot.radius_mm * scale, 4 * px) + 3 * px;
    for (const bumper of sim.bumpers) {
      const start = ((sim.pose.theta_deg + bumper.start_deg) * Math.PI) / 180;
      const end = ((sim.pose.theta_deg + bumper.end_deg) * Math.PI) / 180;
      ctx.strokeStyle = bumper.pressed ? "#ff5a5a" : "rgba(76,211,122,0.5)";
      ctx.lineWidth = (bumper.pressed ? 5 : 2) * px;
      ctx.beginPath();
      ctx.arc(X(sim.pose.x_mm), Y(sim.pose.y_mm), r, -end, -start);
      ctx.stroke();
    }
    for (const cliff of sim.cliff_sensors) dot(ctx, X(cliff.x_mm), Y(cliff.y_mm), 3 * px, cliff.triggered ? "#ff5a5a" : "#8a94a3");
  }

  function drawGrid(ctx, width, height, scale, X, Y, px) {
    const left = view.cx - width / 2 / scale;
    const right = view.cx + width / 2 / scale;
    const bottom = view.cy - height / 2 / scale;
    const top = view.cy + height / 2 / scale;
    const step = scale * 1000 > 40 * px ? 500 : 1000;
    ctx.lineWidth = 1;
    for (let x = Math.floor(left / step) * step; x <= right; x += step) {
      ctx.strokeStyle = x % 1000 === 0 ? "#1f242c" : "#171b21";
      ctx.beginPath();
      ctx.moveTo(X(x), 0);
      ctx.lineTo(X(x), height);
      ctx.stroke();
    }
    for (let y = Math.floor(bottom / step) * step; y <= top; y += step) {
      ctx.strokeStyle = y % 1000 === 0 ? "#1f242c" : "#171b21";
      ctx.beginPath();
      ctx.moveTo(0, Y(y));
      ctx.lineTo(width, Y(y));
      ctx.stroke();
    }
    ctx.fillStyle = "#4a5260";
    ctx.font = `${11 * px}px system-ui, sans-serif`;
    ctx.fillText("grid 1 m", 6 * px, height - 6 * px);
  }

  function drawTrail(ctx, points, X, Y, colour, px) {
    if (points.length < 2) return;
    ctx.strokeStyle = colour;
    ctx.lineWidth = 2 * px;
    ctx.beginPath();
    points.forEach(([x, y], i) => (i ? ctx.lineTo(X(x), Y(y)) : ctx.moveTo(X(x), Y(y))));
    ctx.stroke();
  }

  function drawRobot(ctx, pose, shape, radius, X, Y, scale, colour, px) {
    const cx = X(pose.x_mm);
    const cy = Y(pose.y_mm);
    const r = Math.max(radius * scale, 4 * px);
    const a = (pose.theta_deg * Math.PI) / 180;
    ctx.strokeStyle = colour;
    ctx.lineWidth = 2 * px;
    ctx.beginPath();
    if (shape === "square") {
      ctx.save();
      ctx.translate(cx, cy);
      ctx.rotate(-a);
      ctx.rect(-r, -r, 2 * r, 2 * r);
      ctx.restore();
    } else {
      ctx.arc(cx, cy, r, 0, 2 * Math.PI);
    }
    ctx.stroke();
    ctx.beginPath();
    ctx.moveTo(cx, cy);
    ctx.lineTo(cx + Math.cos(a) * r * 1.3, cy - Math.sin(a) * r * 1.3);
    ctx.stroke();
  }

  function mountToRoom(mount, pose) {
    const a = (pose.theta_deg * Math.PI) / 180;
    return {
      x: pose.x_mm + Math.cos(a) * mount.x_mm - Math.sin(a) * mount.y_mm,
      y: pose.y_mm + Math.sin(a) * mount.x_mm + Math.cos(a) * mount.y_mm,
      angle: ((pose.theta_deg + mount.angle_deg) * Math.PI) / 180,
    };
  }

  function drawSensorRays(ctx, sensors, pose, X, Y, px) {
    ctx.font = `${10 * px}px system-ui, sans-serif`;
    for (const sensor of sensors) {
      const m = mountToRoom(sensor, pose);
      const echo = sensor.distance_mm !== null && sensor.distance_mm > 0;
      const length = echo ? sensor.distance_mm : 300;
      const ex = m.x + Math.cos(m.angle) * length;
      const ey = m.y + Math.sin(m.angle) * length;
      ctx.strokeStyle = echo ? "rgba(77,163,255,0.75)" : "rgba(138,148,163,0.5)";
      ctx.lineWidth = px;
      ctx.setLineDash(echo ? [] : [2 * px, 3 * px]);
      ctx.beginPath();
      ctx.moveTo(X(m.x), Y(m.y));
      ctx.lineTo(X(ex), Y(ey));
      ctx.stroke();
      ctx.setLineDash([]);
      if (echo) {
        dot(ctx, X(ex), Y(ey), 2.5 * px, "#4da3ff");
        ctx.fillStyle = "#9cc9ff";
        ctx.fillText(Math.round(sensor.distance_mm) + "", X(ex) + 4 * px, Y(ey) - 4 * px);
      }
    }
  }

  function drawBumpers(ctx, bumpers, pose, radius, X, Y, scale, px) {
    for (const bumper of bumpers) {
      const m = mountToRoom(bumper, pose);
      const r = Math.max(radius * scale, 4 * px) + 3 * px;
      ctx.strokeStyle = bumper.pressed ? "#ff5a5a" : "rgba(138,148,163,0.8)";
      ctx.lineWidth = (bumper.pressed ? 5 : 3) * px;
      ctx.beginPath();
      ctx.arc(X(pose.x_mm), Y(pose.y_mm), r, -m.angle - 0.35, -m.angle + 0.35);
      ctx.stroke();
    }
  }

  function drawDock(ctx, dock, X, Y, scale, px) {
    const a = (dock.heading_deg * Math.PI) / 180;
    ctx.save();
    ctx.translate(X(dock.x_mm), Y(dock.y_mm));
    ctx.rotate(-a);
    ctx.fillStyle = "#3a4250";
    ctx.fillRect(-60 * scale, -160 * scale, 60 * scale, 320 * scale);
    ctx.strokeStyle = "#f0b429";
    ctx.lineWidth = 2 * px;
    ctx.beginPath();
    ctx.moveTo(0, 0);
    ctx.lineTo(150 * scale, 0);
    ctx.stroke();
    ctx.restore();
    ctx.fillStyle = "#f0b429";
    ctx.font = `${11 * px}px system-ui, sans-serif`;
    ctx.fillText("dock", X(dock.x_mm) + 6 * px, Y(dock.y_mm) + 14 * px);
  }

  function dot(ctx, x, y, r, colour) {
    ctx.fillStyle = colour;
    ctx.beginPath();
    ctx.arc(x, y, r, 0, 2 * Math.PI);
    ctx.fill();
  }

  window.addEventListener("resize", () => drawMap());
  updateSpeedLabel();
  connect();
})();
