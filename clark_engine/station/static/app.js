/* Clark station view: the page's script. Plain JavaScript, no build step.
 *
 * It opens the WebSocket /ws of the page's own server (the token travels in the cookie
 * the server set), draws `hello` (the mission, its agents, its plan) and each `state`
 * (the agents, new track points, photos and mission-log lines, the commands and their
 * lifecycle, the alarms), and sends the operator's commands. Each vehicle's envelope
 * (geofence zones, ceiling) comes in `hello`; its health (armed, battery, GPS, pre-arm,
 * the autopilot's latest warning) in each row of `state`. Everything received is written
 * as text (textContent), never as HTML. Protocol: docs/station-view.md.
 *
 * In a replay (`clark replay LOGS`, hello.mode "replay") there are no controls: a time
 * slider, play/pause and a speed choice send `seek`, `play`, `pause` and `speed`; the
 * server answers with a `reset` (tracks, photos and log up to the time, drawn afresh)
 * when the time jumps, and a `state` for each time shown.
 */
(function () {
  "use strict";

  var MAX_TRACK_POINTS = 5000; // per agent, on the map
  var MAX_PHOTOS = 2000; // photo markers on the map, the newest (as many as the server keeps)
  var photoMarkers = []; // oldest first
  var MAX_LOG_ITEMS = 500;
  var RECONNECT_MS = 2000;
  var SEVERITIES = ["EMERGENCY", "ALERT", "CRITICAL", "ERROR", "WARNING"];
  var GPS_FIXES = ["no GPS", "no fix", "2-D fix", "3-D fix", "DGPS", "RTK float", "RTK fixed", "static", "PPP"];
  var LOW_BATTERY_PCT = 20;
  var CLASS_SAFE = /^[a-z][a-z0-9_]*$/; // mission names: usable in a class name as they are
  var PALETTE = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf",
    "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22"];

  var hello = null;
  var stationStopped = false; // the server said so as it closed (code 1001)
  var socket = null;
  var nextRef = 1;
  var map = null;
  var layers = null;
  var agentLayers = {}; // id -> {marker, heading, track, points}
  var rows = {}; // name -> {row, cells, select}
  var replay = false; // hello.mode === "replay"
  var replayTime = null; // the time shown, kept across reconnections
  var dragging = false; // the slider is being moved: states do not move it back
  var SEEK_EVERY_MS = 200; // a dragged slider sends at most 5 seeks a second
  var lastSeekMs = 0;
  var seekTimer = null;

  function $(id) { return document.getElementById(id); }

  function el(tag, attrs, text) {
    var node = document.createElement(tag);
    if (attrs) {
      Object.keys(attrs).forEach(function (key) { node.setAttribute(key, attrs[key]); });
    }
    if (text !== undefined && text !== null) { node.textContent = String(text); }
    return node;
  }

  // Leaflet writes a string tooltip as HTML: every tooltip is given a text node instead.
  function text(value) { return el("span", null, value); }

  function fixed(value, digits) {
    return (value === null || value === undefined) ? "–" : Number(value).toFixed(digits);
  }

  function colourOf(agentId) {
    var index = 0;
    if (hello) {
      hello.agents.forEach(function (a, i) { if (a.id === agentId) { index = i; } });
    }
    return PALETTE[index % PALETTE.length];
  }

  // -- connection ------------------------------------------------------------------------

  function setConnection(kind, text) {
    var node = $("connection");
    node.className = "conn conn-" + kind;
    node.textContent = text;
  }

  function connect() {
    var scheme = location.protocol === "https:" ? "wss://" : "ws://";
    setConnection("connecting", "connecting");
    socket = new WebSocket(scheme + location.host + "/ws");
    socket.onopen = function () { setConnection("open", replay ? "replay" : "live"); };
    socket.onmessage = function (event) {
      var message;
      try { message = JSON.parse(event.data); } catch (e) { return; }
      if (message.type === "hello") { onHello(message); }
      else if (message.type === "state") { onState(message); }
      else if (message.type === "reset") { onReset(message); }
      else if (message.type === "accepted") { showCommandError(""); }
      else if (message.type === "error") { showCommandError("refused by the view: " + message.error); }
    };
    socket.onclose = function (event) {
      if (event.code === 1001) { stationStopped = true; }
      var why = stationStopped ? (replay ? "the replay stopped" : "the station stopped") : "disconnected";
      setConnection("closed", why + "; retrying");
      setControlsEnabled(false);
      setTimeout(connect, RECONNECT_MS);
    };
  }

  function send(command) {
    if (!socket || socket.readyState !== WebSocket.OPEN) {
      showCommandError("not connected");
      return;
    }
    command.type = "command";
    command.ref = nextRef++;
    command.operator = $("operator").value.slice(0, 40);
    socket.send(JSON.stringify(command));
  }

  function showCommandError(text) {
    $("command-error").textContent = text;
    if (replay && text) { $("replay-time").textContent = text; }
  }

  function sendControl(message) {
    if (socket && socket.readyState === WebSocket.OPEN) { socket.send(JSON.stringify(message)); }
  }

  function setControlsEnabled(enabled) {
    var buttons = document.querySelectorAll("#fleet-pane button, #fleet-pane select");
    Array.prototype.forEach.call(buttons, function (b) { b.disabled = !enabled; });
  }

  // -- hello -----------------------------------------------------------------------------

  function onHello(message) {
    hello = message;
    stationStopped = false;
    replay = message.mode === "replay";
    document.body.classList.toggle("replay", replay);
    $("replay-bar").hidden = !replay;
    var mission = message.mission;
    $("mission-name").textContent = mission.name + " (mission " + mission.id + ")";
    $("mission-detail").textContent = replay
      ? "replay of " + message.replay.folder + " · station " + (message.station.name || "none logged") +
        (message.plan_source ? " · plan from " + message.plan_source : " · no plan known")
      : "station " + message.station.name +
        (mission.authenticated ? " · authenticated" : " · NOT authenticated") +
        (message.plan_source ? " · plan from " + message.plan_source : " · no plan known");
    buildTable(message.agents);
    buildTerminateTargets(message.agents);
    buildMap(message);
    $("mission-log").textContent = "";
    if (replay) {
      setConnection("open", "replay");
      buildReplayBar(message.replay);
      if (replayTime !== null) { sendControl({ type: "seek", t: replayTime }); } // after a reconnection
    } else {
      setControlsEnabled(true);
    }
  }

  // -- the replay's time slider ------------------------------------------------------------

  function showTime(t) {
    var info = hello.replay;
    $("replay-time").textContent = "t = " + fixed(t, 1) + " s (" + fixed(info.start_s, 1) + " to " +
      fixed(info.end_s, 1) + " s)";
  }

  function seek(t, now) {
    var send = function () { lastSeekMs = Date.now(); seekTimer = null; sendControl({ type: "seek", t: t }); };
    if (seekTimer) { clearTimeout(seekTimer); seekTimer = null; }
    if (now || Date.now() - lastSeekMs >= SEEK_EVERY_MS) { send(); }
    else { seekTimer = setTimeout(send, SEEK_EVERY_MS); }
  }

  function buildReplayBar(info) {
    var slider = $("replay-slider");
    slider.min = String(info.start_s);
    slider.max = String(info.end_s);
    slider.value = String(info.start_s);
    var speed = $("replay-speed");
    speed.textContent = "";
    info.speeds.forEach(function (x) { speed.appendChild(el("option", { value: String(x) }, x + "x")); });
    showTime(info.start_s);
    slider.oninput = function () { dragging = true; showTime(Number(slider.value)); seek(Number(slider.value), false); };
    slider.onchange = function () { dragging = false; seek(Number(slider.value), true); };
    $("replay-play").onclick = function () {
      sendControl({ type: $("replay-play").getAttribute("data-playing") === "true" ? "pause" : "play" });
    };
    speed.onchange = function () { sendControl({ type: "speed", speed: Number(speed.value) }); };
    var note = $("checks-note");
    note.textContent = info.checks_note || "";
    note.hidden = !info.checks_note;
  }

  function updateReplayBar(info) {
    replayTime = info.t;
    if (!dragging) { $("replay-slider").value = String(info.t); showTime(info.t); }
    var play = $("replay-play");
    play.textContent = info.playing ? "Pause" : "Play";
    play.setAttribute("data-playing", info.playing ? "true" : "false");
    $("replay-speed").value = String(info.speed);
  }

  // A jump in time: what was drawn up to the old time goes; what is up to the new one comes.
  function onReset(message) {
    if (!hello) { return; }
    Object.keys(agentLayers).forEach(function (id) { agentLayers[id].points = []; agentLayers[id].track.setLatLngs([]); });
    layers.photos.clearLayers();
    photoMarkers = [];
    $("mission-log").textContent = "";
    $("log-count").textContent = "";
    updateMap({ track: message.track, photos: message.photos, agents: [] });
    updateLog(message.log);
  }

  function buildTable(agents) {
    var body = $("agents-body");
    body.textContent = "";
    rows = {};
    agents.forEach(function (agent) {
      var row = el("tr", { "data-testid": "agent-row-" + agent.name, "data-agent": agent.name });
      var cells = {};
      var controls = el("td", { "data-field": "controls", "class": "controls" });
      ["name", "controls", "airframe", "liveness", "heard", "mode", "armed", "battery", "gps", "prearm",
        "autopilot", "behaviour", "condition", "local", "latlon", "alt", "ceiling", "speed", "heading",
        "link"].forEach(function (field) {
        var cell = field === "controls" ? controls : el("td", { "data-field": field });
        cells[field] = cell;
        row.appendChild(cell);
      });
      cells.name.textContent = agent.name + " #" + agent.id;
      cells.name.style.borderLeftColor = colourOf(agent.id);
      cells.name.className = "agent-name";
      cells.airframe.textContent = agent.airframe || (agent.role === "mcs" ? "station" : "–");
      cells.ceiling.textContent = agent.envelope ? fixed(agent.envelope.ceiling_m, 0) : "–";
      var select = null;
      if (agent.role !== "mcs" && !replay) {
        var activate = el("button", { type: "button", "data-testid": "activate-" + agent.name }, "Activate");
        activate.onclick = function () { send({ action: "activate", target: agent.name }); };
        var deactivate = el("button", { type: "button", "data-testid": "deactivate-" + agent.name }, "Deactivate");
        deactivate.onclick = function () { send({ action: "deactivate", target: agent.name }); };
        controls.appendChild(activate);
        controls.appendChild(deactivate);
        if (agent.modes.length) {
          select = el("select", { "data-testid": "mode-select-" + agent.name, "aria-label": "mode for " + agent.name });
          agent.modes.forEach(function (mode) { select.appendChild(el("option", { value: mode.name }, mode.name)); });
          var setMode = el("button", { type: "button", "data-testid": "mode-set-" + agent.name }, "Set mode");
          // The drop-down follows the agent's mode until the operator picks one.
          select.onchange = function () { select.setAttribute("data-chosen", "1"); };
          setMode.onclick = function () {
            send({ action: "mode", target: agent.name, mode: select.value });
            select.removeAttribute("data-chosen");
          };
          controls.appendChild(select);
          controls.appendChild(setMode);
        }
      }
      body.appendChild(row);
      rows[agent.name] = { row: row, cells: cells, select: select };
    });
  }

  function buildTerminateTargets(agents) {
    var select = $("terminate-target");
    select.textContent = "";
    select.appendChild(el("option", { value: "" }, "choose…"));
    select.appendChild(el("option", { value: "all" }, "all (ends the mission)"));
    agents.forEach(function (agent) {
      if (agent.role !== "mcs") { select.appendChild(el("option", { value: agent.name }, agent.name)); }
    });
  }

  // -- the map ---------------------------------------------------------------------------

  function ll(point) { return [point.north_m, point.east_m]; }

  function buildMap(message) {
    if (map) { map.remove(); }
    agentLayers = {};
    photoMarkers = [];
    map = L.map("map", { crs: L.CRS.Simple, minZoom: -6, maxZoom: 6, zoomSnap: 0.25, attributionControl: false });
    L.control.scale({ metric: true, imperial: false, maxWidth: 150 }).addTo(map);
    layers = { envelope: L.layerGroup().addTo(map), plan: L.layerGroup().addTo(map),
      tracks: L.layerGroup().addTo(map), photos: L.layerGroup().addTo(map),
      agents: L.layerGroup().addTo(map) };
    var bounds = L.latLngBounds([[0, 0], [0, 0]]);
    L.circleMarker([0, 0], { radius: 3, color: "#444", weight: 1, fillOpacity: 1 })
      .bindTooltip(text("origin")).addTo(layers.plan);
    if (message.station.home) {
      L.circleMarker(ll(message.station.home), { radius: 6, color: "#000", weight: 2, fillColor: "#fff", fillOpacity: 1 })
        .bindTooltip(text("station " + message.station.name)).addTo(layers.plan);
      bounds.extend(ll(message.station.home));
    }
    message.agents.forEach(function (agent) {
      var colour = colourOf(agent.id);
      drawEnvelope(agent, colour, bounds);
      if (agent.home) {
        L.circleMarker(ll(agent.home), { radius: 4, color: colour, weight: 1, fillOpacity: 0.2 })
          .bindTooltip(text(agent.name + " start")).addTo(layers.plan);
        bounds.extend(ll(agent.home));
      }
      (message.plan[agent.name] || []).forEach(function (item) {
        var points = item.points.map(ll);
        points.forEach(function (p) { bounds.extend(p); });
        if (item.kind === "tour") {
          var path = item.loop ? points.concat([points[0]]) : points;
          L.polyline(path, { color: colour, weight: item.survey ? 4 : 2, opacity: 0.6,
            dashArray: item.survey ? null : "6 6" })
            .bindTooltip(text(agent.name + ": " + (item.survey ? "survey line" : "tour") + " (" + item.state + ")"))
            .addTo(layers.plan);
        }
        points.forEach(function (p, i) {
          L.circleMarker(p, { radius: 3, color: colour, weight: 1, fillColor: colour, fillOpacity: 0.5 })
            .bindTooltip(text(agent.name + " " + item.primitive + " " + (i + 1) + " (" + item.state + ")"))
            .addTo(layers.plan);
        });
      });
      var marker = L.circleMarker([0, 0], { radius: 8, color: "#000", weight: 2, fillColor: colour, fillOpacity: 0.9 });
      marker.bindTooltip(text(agent.name), { permanent: true, direction: "right", offset: [10, 0], className: "agent-label" });
      var heading = L.polyline([[0, 0], [0, 0]], { color: "#000", weight: 2 });
      var track = L.polyline([], { color: colour, weight: 2, opacity: 0.8 }).addTo(layers.tracks);
      agentLayers[agent.id] = { marker: marker, heading: heading, track: track, points: [], shown: false };
    });
    var padded = bounds.pad(0.2);
    if (padded.getNorth() - padded.getSouth() < 20) { padded = L.latLngBounds([[-30, -30], [30, 30]]).extend(padded); }
    map.fitBounds(padded);
  }

  // A vehicle's geofence: its inclusion zones dashed in its colour (the default circle
  // around its start too), its exclusion zones filled red. Declared zones widen the view;
  // the default circle (a radio's range, often a mile) does not.
  function drawEnvelope(agent, colour, bounds) {
    var envelope = agent.envelope;
    if (!envelope) { return; }
    var who = CLASS_SAFE.test(agent.name) ? " envelope-of-" + agent.name : "";
    var zone = function (item, inclusion) {
      var style = inclusion
        ? { color: colour, weight: 1.5, opacity: 0.7, dashArray: "8 6", fill: false,
            className: "envelope envelope-include" + who }
        : { color: "#b00020", weight: 1.5, opacity: 0.9, fillColor: "#b00020", fillOpacity: 0.12,
            className: "envelope envelope-exclude" + who };
      var shape;
      if (item.kind === "circle") {
        shape = L.circle(ll(item.center), Object.assign({ radius: item.radius_m }, style));
      } else {
        shape = L.polygon(item.points.map(ll), style);
      }
      var isDefault = inclusion && envelope.default_radius_m !== null;
      var label = agent.name + ": " + (inclusion
        ? (isDefault ? "geofence, " + fixed(envelope.default_radius_m, 0) + " m around its start (default)" : "geofence")
        : "excluded zone") + "; ceiling " + fixed(envelope.ceiling_m, 0) + " m";
      shape.bindTooltip(text(label), { sticky: true }).addTo(layers.envelope);
      if (!isDefault) { bounds.extend(shape.getBounds()); }
    };
    envelope.include.forEach(function (item) { zone(item, true); });
    envelope.exclude.forEach(function (item) { zone(item, false); });
  }

  function updateMap(message) {
    // Only the tracks that grew are handed to Leaflet again (it projects every point of a
    // track it is given), and a full track drops its oldest points in one splice, not one
    // shift (a 5,000-slot move) per point.
    var grown = {};
    message.track.forEach(function (point) {
      var layer = agentLayers[point.agent];
      if (!layer) { return; }
      layer.points.push([point.north_m, point.east_m]);
      grown[point.agent] = layer;
    });
    Object.keys(grown).forEach(function (id) {
      var layer = grown[id];
      var excess = layer.points.length - MAX_TRACK_POINTS;
      if (excess > 0) { layer.points.splice(0, excess); }
      layer.track.setLatLngs(layer.points);
    });
    message.photos.forEach(function (photo) {
      if (photo.north_m === null || photo.east_m === null) { return; }
      var marker = L.circleMarker([photo.north_m, photo.east_m], { radius: 3, color: "#333", weight: 1, fillColor: "#ffd700", fillOpacity: 1 })
        .bindTooltip(text("photo " + photo.image_index + " by #" + photo.agent + " at " + fixed(photo.alt_m, 1) + " m"))
        .addTo(layers.photos);
      photoMarkers.push(marker);
    });
    if (photoMarkers.length > MAX_PHOTOS) {  // bounded like the tracks: the oldest go
      photoMarkers.splice(0, photoMarkers.length - MAX_PHOTOS).forEach(function (old) { layers.photos.removeLayer(old); });
    }
    message.agents.forEach(function (agent) {
      var layer = agentLayers[agent.id];
      if (!layer) { return; }
      if (!agent.position) {
        if (layer.shown) { layers.agents.removeLayer(layer.marker); layers.agents.removeLayer(layer.heading); layer.shown = false; }
        return;
      }
      var p = [agent.position.north_m, agent.position.east_m];
      var rad = (agent.position.heading_deg || 0) * Math.PI / 180;
      var length = 6;
      layer.marker.setLatLng(p);
      layer.heading.setLatLngs([p, [p[0] + length * Math.cos(rad), p[1] + length * Math.sin(rad)]]);
      // Style and label only when they change: a permanent tooltip's new content makes
      // Leaflet measure it at once, a forced layout per agent per update (98 ms an update
      // with 100 agents, measured: docs/performance.md).
      var faded = Boolean(agent.lost || agent.stale || agent.condition === "terminated");
      if (layer.faded !== faded) {
        layer.faded = faded;
        layer.marker.setStyle({ fillOpacity: faded ? 0.3 : 0.9, dashArray: faded ? "3 3" : null });
      }
      var alarm = Boolean(agent.alarm);
      if (layer.alarm !== alarm) {
        layer.alarm = alarm;
        layer.marker.setStyle({ color: alarm ? "#b00020" : "#000", weight: alarm ? 4 : 2 });
      }
      var label = agent.name + (agent.lost ? " (LOST)" : agent.stale ? " (STALE)" : "");
      if (layer.label !== label) {
        layer.label = label;
        layer.marker.setTooltipContent(text(label));
      }
      if (!layer.shown) { layer.marker.addTo(layers.agents); layer.heading.addTo(layers.agents); layer.shown = true; }
    });
  }

  // -- state -----------------------------------------------------------------------------

  function liveness(agent) {
    if (!agent.heard) { return ["not-heard", "not heard"]; }
    // A terminated agent sends no more heartbeats: it turns stale, then lost, by design.
    if (agent.condition === "terminated") { return ["terminated", agent.lost ? "TERMINATED (lost)" : "TERMINATED"]; }
    if (agent.lost) { return ["lost", "LOST"]; }
    if (agent.stale) { return ["stale", "STALE"]; }
    return ["ok", "live"];
  }

  function onState(message) {
    if (!hello) { return; }
    var station = message.station;
    $("station-clock").textContent = "t = " + fixed(message.t, 1) + " s" +
      (station.terminated ? " · station TERMINATED" : "");
    if (station.terminated && !replay) { setControlsEnabled(false); }
    if (replay && message.replay) { updateReplayBar(message.replay); }
    message.agents.forEach(updateRow);
    updateAlarms(message.alarms || []);
    updateMap(message);
    updateLog(message.log);
    updateCommands(message.commands);
    updateChecks(message.checks);
  }

  // A cell's text or an attribute, written only when it changes: every write dirties the
  // page's style and layout, which each agent's map label then measures again.
  function put(node, value) {
    if (node.textContent !== value) { node.textContent = value; }
  }

  function attr(node, name, value) {
    if (node.getAttribute(name) !== value) { node.setAttribute(name, value); }
  }

  function updateRow(agent) {
    var entry = rows[agent.name];
    if (!entry) { return; }
    var c = entry.cells;
    var live = liveness(agent);
    attr(entry.row, "class", "agent agent-" + live[0] + (agent.alarm ? " agent-alarm" : ""));
    attr(entry.row, "data-liveness", live[0]);
    put(c.liveness, live[1]);
    put(c.heard, agent.since_heartbeat_s === null ? "never" : fixed(agent.since_heartbeat_s, 1) + " s ago");
    put(c.mode, agent.mode ? (agent.mode.name || "?") + " (" + agent.mode.number + ")" : "–");
    var chooser = entry.select;
    if (chooser && agent.mode && agent.mode.name && !chooser.hasAttribute("data-chosen") &&
        document.activeElement !== chooser &&
        Array.prototype.some.call(chooser.options, function (o) { return o.value === agent.mode.name; })) {
      chooser.value = agent.mode.name;
    }
    put(c.armed, agent.armed === null ? "unknown" : (agent.armed ? "ARMED" : "disarmed"));
    attr(entry.row, "data-alarm", agent.alarm ? "1" : "0");
    updateHealth(c, agent.health);
    put(c.behaviour, agent.behaviour
      ? (agent.behaviour.active.map(function (path) { return path || "(behaviour)"; }).join(", ") || "(none)") + (agent.behaviour.last_event ? " ← " + agent.behaviour.last_event : "")
      : "–");
    // The failsafe in force and why, from its health; a terminated vehicle's has ended.
    var failsafe = agent.health && agent.health.failsafe && agent.condition !== "terminated"
      ? " (" + agent.health.failsafe + ")" : "";
    put(c.condition, (agent.condition || "–") + failsafe);
    attr(c.condition, "class", agent.condition && agent.condition !== "ok" ? "condition-bad" : "");
    var pos = agent.position;
    put(c.local, pos ? fixed(pos.north_m, 1) + ", " + fixed(pos.east_m, 1) : "–");
    put(c.latlon, pos ? fixed(pos.lat, 7) + ", " + fixed(pos.lon, 7) : "–");
    put(c.alt, pos ? fixed(pos.alt_m, 1) : "–");
    put(c.speed, pos ? fixed(pos.ground_speed_m_s, 1) : "–");
    put(c.heading, pos ? fixed(pos.heading_deg, 0) : "–");
    var link = agent.link;
    put(c.link, link
      ? link.packets + " pkts, loss " + (link.loss_ratio === null ? "–" : (100 * link.loss_ratio).toFixed(1) + " %") +
        ", " + (link.latency_mean_ms === null ? "–" : fixed(link.latency_mean_ms, 0) + " ms")
      : "–");
  }

  // Battery, GPS, pre-arm and the autopilot's latest warning, from the Vehicle Health.
  function updateHealth(c, h) {
    var mark = function (cell, bad) { attr(cell, "class", bad ? "health-bad" : ""); };
    if (!h) {
      ["battery", "gps", "prearm", "autopilot"].forEach(function (f) { put(c[f], "–"); mark(c[f], false); });
      return;
    }
    put(c.battery, (h.battery_v === null ? "? V" : fixed(h.battery_v, 1) + " V") +
      (h.battery_pct === null ? "" : " " + h.battery_pct + " %"));
    mark(c.battery, h.battery_pct !== null && h.battery_pct <= LOW_BATTERY_PCT);
    put(c.gps, (GPS_FIXES[h.gps_fix_type] || "fix type " + h.gps_fix_type) +
      (h.satellites === null ? "" : ", " + h.satellites + " sats"));
    mark(c.gps, h.gps_fix_type < 3);
    put(c.prearm, h.prearm === "failing" ? "FAILING" : h.prearm);
    mark(c.prearm, h.prearm === "failing");
    var says = h.text === null ? "–"
      : (SEVERITIES[h.text_severity] || "?") + ": " + h.text + " (" + fixed(h.text_age_s, 0) + " s ago)";
    put(c.autopilot, (h.autopilot_lost ? "AUTOPILOT LOST · " : "") + says);
    mark(c.autopilot, h.autopilot_lost || (h.text !== null && h.text_severity <= 2));
  }

  // The banner: every alarm in force, and those cleared in the last seconds (greyed).
  function updateAlarms(alarms) {
    var banner = $("alarms");
    var list = $("alarm-list");
    banner.hidden = alarms.length === 0;
    banner.classList.toggle("alarms-active", alarms.some(function (a) { return a.cleared_s === null; }));
    list.textContent = "";
    alarms.forEach(function (alarm) {
      var active = alarm.cleared_s === null;
      var item = el("li", { "data-testid": "alarm-" + alarm.id, "data-kind": alarm.kind,
        "data-status": active ? "active" : "cleared", "class": "alarm alarm-" + (active ? "active" : "cleared") });
      item.appendChild(el("span", { "class": "alarm-kind" }, String(alarm.kind).toUpperCase()));
      item.appendChild(el("span", { "class": "alarm-text" }, alarm.text));
      item.appendChild(el("span", { "class": "alarm-time" }, active
        ? "since t = " + fixed(alarm.raised_s, 1) + " s"
        : "cleared at t = " + fixed(alarm.cleared_s, 1) + " s (raised " + fixed(alarm.raised_s, 1) + " s)"));
      list.appendChild(item);
    });
  }

  function updateLog(lines) {
    if (!lines.length) { return; }
    var list = $("mission-log");
    var atBottom = list.scrollTop + list.clientHeight >= list.scrollHeight - 4;
    lines.forEach(function (line) {
      var item = el("li", { "class": "log-" + String(line.level).toLowerCase(), "data-seq": line.seq });
      item.appendChild(el("span", { "class": "log-time" }, fixed(line.t, 1)));
      item.appendChild(el("span", { "class": "log-level" }, line.level));
      item.appendChild(el("span", { "class": "log-text" }, line.text));
      list.appendChild(item);
    });
    while (list.children.length > MAX_LOG_ITEMS) { list.removeChild(list.firstChild); }
    $("log-count").textContent = "(last " + list.children.length + ")";
    if (atBottom) { list.scrollTop = list.scrollHeight; }
  }

  function updateCommands(commands) {
    var list = $("commands");
    list.textContent = "";
    commands.slice().reverse().forEach(function (command) {
      var item = el("li", { "data-testid": "command-" + command.id, "data-status": command.status,
        "class": "command command-" + command.status });
      var what = command.action + " " + command.target + (command.mode ? " " + command.mode : "");
      item.appendChild(el("span", { "class": "command-status" }, command.status));
      item.appendChild(el("span", { "class": "command-what" }, "#" + command.id + " " + what));
      item.appendChild(el("span", { "class": "command-by" },
        "by " + (command.by.name || "(no name)") + " at " + command.by.address + ", t = " + fixed(command.sent_s, 1) + " s"));
      if (command.detail) { item.appendChild(el("span", { "class": "command-detail" }, command.detail)); }
      list.appendChild(item);
    });
  }

  function updateChecks(checks) {
    var list = $("checks");
    var none = $("checks-none");
    none.hidden = checks !== null && checks !== undefined;
    if (replay) { none.textContent = "No checks are judged in this replay."; }
    list.textContent = "";
    (checks || []).forEach(function (check) {
      // "not evaluated" holds a space: the class takes the status with dashes for spaces.
      var kind = String(check.status).replace(/[^a-z]+/gi, "-");
      var item = el("li", { "data-status": check.status, "class": "check check-" + kind });
      item.textContent = check.status + ": " + check.name + (check.detail ? " (" + check.detail + ")" : "");
      list.appendChild(item);
    });
  }

  // -- controls --------------------------------------------------------------------------

  function wireControls() {
    var operator = $("operator");
    try { operator.value = localStorage.getItem("clark-operator") || ""; } catch (e) { /* private mode */ }
    operator.onchange = function () {
      try { localStorage.setItem("clark-operator", operator.value.slice(0, 40)); } catch (e) { /* ignore */ }
    };
    $("activate-all").onclick = function () { send({ action: "activate", target: "all" }); };
    $("deactivate-all").onclick = function () { send({ action: "deactivate", target: "all" }); };
    var dialog = $("terminate-dialog");
    var target = $("terminate-target");
    var confirm = $("terminate-confirm");
    // No target is chosen in advance: the operator picks one each time (never a leftover "all").
    target.onchange = function () { confirm.disabled = !target.value; };
    $("terminate-open").onclick = function () {
      target.value = "";
      confirm.disabled = true;
      dialog.showModal();
    };
    $("terminate-cancel").onclick = function () { dialog.close(); };
    confirm.onclick = function () {
      if (!target.value) { return; }
      send({ action: "terminate", target: target.value, confirm: true });
      dialog.close();
    };
    setControlsEnabled(false);
  }

  wireControls();
  connect();
}());
