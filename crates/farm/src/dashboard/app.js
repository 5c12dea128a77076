// Kiln's farm dashboard: signs in with a token (the admin's, or a submitter's: the page shows
// only what the role may do; a worker's credential is refused), then polls the HTTP API
// (GET /v1/jobs, /v1/workers, and a shot's /v1/jobs/{id}/frames) once a second and draws
// what it says: a shot's frames as a strip of thumbnails, each with its progress. Images and downloads
// are fetched with the token and shown through object URLs, since an <img> or <a> cannot
// send an Authorization header. No framework, no build step: this file is served as is.
"use strict";

const POLL_MS = 1000;
const $ = (id) => document.getElementById(id);

const state = {
  token: sessionStorage.getItem("kiln-token"),
  role: null, // "admin" or "submitter", as the coordinator says
  name: null,
  selected: null, // the job shown
  frame: 0, // the frame of the shot shown
  shown: null, // what the frame on screen was drawn from
  frameUrl: null,
  thumbs: [], // per frame of the shown shot: { key, url } of its thumbnail
  jobThumbs: new Map(), // per job: { key, url } of its list thumbnail
  frames: null, // the shown shot's frames, as last listed
  timer: null,
};

/// Thumbnails fetched per poll at most: a long shot's fill in over a few seconds.
const THUMBS_PER_POLL = 8;

/// Calls the API; returns the response, or throws an Error with the server's message.
async function api(method, path, body) {
  const headers = {};
  if (state.token) headers["Authorization"] = "Bearer " + state.token;
  if (body !== undefined) headers["Content-Type"] = "application/json";
  const r = await fetch(path, {
    method,
    headers,
    body: body === undefined ? undefined : JSON.stringify(body),
  });
  if (!r.ok) {
    let message = r.status + " " + r.statusText;
    try {
      message = (await r.json()).error || message;
    } catch (_) {
      // Not JSON: keep the status line.
    }
    const e = new Error(message);
    e.status = r.status;
    throw e;
  }
  return r;
}

function say(text) {
  $("message").textContent = text;
}

function fmtSeconds(s) {
  if (s === null || s === undefined || !isFinite(s)) return "–";
  if (s < 90) return Math.round(s) + " s";
  if (s < 5400) return Math.round(s / 60) + " min";
  return (s / 3600).toFixed(1) + " h";
}

function cell(tr, content) {
  const td = document.createElement("td");
  if (content instanceof Node) td.appendChild(content);
  else td.textContent = content;
  tr.appendChild(td);
  return td;
}

// ---- signing in -----------------------------------------------------------------------

async function signIn(token) {
  try {
    const r = await api("POST", "/v1/token/check", { token: token || "" });
    const who = await r.json();
    if (!who.valid) {
      $("sign-in-error").textContent = "That token is not the coordinator's, or it was revoked.";
      return;
    }
    if (who.role === "worker") {
      $("sign-in-error").textContent = "That is a worker's credential: workers do not use the dashboard.";
      return;
    }
    state.role = who.role;
    state.name = who.name;
  } catch (e) {
    $("sign-in-error").textContent = "Cannot reach the coordinator: " + e.message;
    return;
  }
  state.token = token || null;
  // Kept for this tab only (an empty one too, for a coordinator without a token).
  sessionStorage.setItem("kiln-token", token || "");
  $("sign-in-error").textContent = "";
  $("sign-in").hidden = true;
  $("farm").hidden = false;
  $("sign-out").hidden = false;
  const admin = state.role === "admin";
  // A submitter sees its own jobs only; workers and tokens are the admin's.
  $("workers-panel").hidden = !admin;
  $("tokens-panel").hidden = !admin;
  $("who").textContent = `Signed in as ${state.name} (${state.role})`;
  say("Signed in.");
  poll();
}

function signOut() {
  sessionStorage.removeItem("kiln-token");
  state.token = null;
  state.role = null;
  state.selected = null;
  clearTimeout(state.timer);
  $("job").hidden = true;
  $("who").textContent = "";
  $("token-new").hidden = true;
  $("farm").hidden = true;
  $("sign-out").hidden = true;
  $("sign-in").hidden = false;
  $("token").value = "";
  $("token").focus();
  say("Signed out.");
}

// ---- polling ------------------------------------------------------------------------

async function poll() {
  clearTimeout(state.timer);
  try {
    const admin = state.role === "admin";
    const [jobs, workers, tokens] = await Promise.all([
      api("GET", "/v1/jobs").then((r) => r.json()),
      admin ? api("GET", "/v1/workers").then((r) => r.json()) : null,
      admin ? api("GET", "/v1/tokens").then((r) => r.json()) : null,
    ]);
    drawJobs(jobs);
    if (workers) drawWorkers(workers);
    if (tokens) drawTokens(tokens);
    const job = jobs.find((j) => j.id === state.selected);
    if (job) await drawJob(job);
  } catch (e) {
    if (e.status === 401) {
      signOut();
      $("sign-in-error").textContent = "The coordinator no longer takes that token.";
      return;
    }
    say("Cannot reach the coordinator: " + e.message);
  }
  if (state.token !== undefined && !$("farm").hidden) state.timer = setTimeout(poll, POLL_MS);
}

function drawJobs(jobs) {
  const body = $("jobs").tBodies[0];
  body.replaceChildren();
  $("no-jobs").hidden = jobs.length > 0;
  // Newest first.
  for (const j of [...jobs].reverse()) {
    const tr = document.createElement("tr");
    tr.dataset.job = j.id;
    if (j.id === state.selected) tr.className = "selected";
    const pick = document.createElement("button");
    pick.type = "button";
    pick.className = "link";
    pick.textContent = "Job " + j.id + (j.frame_count > 1 ? ` (${j.frame_count} frames)` : "");
    pick.setAttribute("aria-label", "Show job " + j.id);
    pick.addEventListener("click", () => select(j.id));
    cell(tr, pick);
    const thumb = document.createElement("img");
    thumb.className = "job-thumb";
    thumb.alt = "Job " + j.id + "'s picture so far";
    const had = state.jobThumbs.get(j.id);
    if (had) thumb.src = had.url;
    cell(tr, thumb);
    cell(tr, j.state).className = "state-" + j.state;
    const bar = document.createElement("progress");
    bar.max = 1;
    bar.value = j.progress;
    bar.setAttribute("aria-label", "Job " + j.id + " progress");
    const td = cell(tr, bar);
    td.append(" " + Math.floor(j.progress * 100) + "%");
    cell(tr, j.samples_per_pixel_done + " / " + (j.passes[j.passes.length - 1] || 0));
    cell(tr, j.passes_done + " / " + j.passes.length);
    cell(tr, j.state === "running" ? fmtSeconds(j.eta_seconds) : "–");
    cell(tr, String(j.priority));
    body.appendChild(tr);
  }
  refreshJobThumbs(jobs);
}

/// Fetches the list's thumbnails of jobs whose picture moved on (the first frame of a
/// shot), a few per poll, newest first; they show from the next drawing of the list.
async function refreshJobThumbs(jobs) {
  let fetched = 0;
  for (const j of [...jobs].reverse()) {
    const key = [j.samples_done, j.passes_done, j.state].join(":");
    const had = state.jobThumbs.get(j.id);
    if ((had && had.key === key) || fetched >= THUMBS_PER_POLL / 2) continue;
    fetched++;
    try {
      const blob = await (await api("GET", `/v1/jobs/${j.id}/preview.png`)).blob();
      const url = URL.createObjectURL(blob);
      if (had) URL.revokeObjectURL(had.url);
      state.jobThumbs.set(j.id, { key, url });
      const img = document.querySelector(`#jobs tr[data-job="${j.id}"] img.job-thumb`);
      if (img) img.src = url;
    } catch (e) {
      // A job gone or not yet planned: its thumbnail waits for the next poll.
    }
  }
}

function drawWorkers(workers) {
  // Pools: the workers that offer each tag, and how many of them are rendering.
  const pools = new Map();
  for (const w of workers) {
    if (w.set_aside) continue;
    for (const t of w.tags || []) {
      const p = pools.get(t) || { all: 0, busy: 0 };
      p.all++;
      if (w.leases.length) p.busy++;
      pools.set(t, p);
    }
  }
  $("pools").textContent = pools.size
    ? "Pools: " + [...pools].sort().map(([t, p]) => `${t} ${p.busy}/${p.all} busy`).join(", ")
    : "";
  const body = $("workers").tBodies[0];
  body.replaceChildren();
  $("no-workers").hidden = workers.length > 0;
  for (const w of workers) {
    const tr = document.createElement("tr");
    cell(tr, w.name);
    cell(
      tr,
      w.leases.length
        ? w.leases.map((l) => `job ${l.job} tile ${l.tile_index} pass ${l.pass.index + 1}`).join(", ")
        : "idle",
    );
    cell(tr, String(w.tiles_done));
    cell(tr, String(w.failures));
    cell(tr, w.last_seen_seconds === null ? "never" : fmtSeconds(w.last_seen_seconds) + " ago");
    const aside = cell(tr, w.set_aside || "–");
    if (w.set_aside) {
      aside.className = "error";
      const again = document.createElement("button");
      again.type = "button";
      again.textContent = "Reinstate";
      again.setAttribute("aria-label", "Reinstate worker " + w.name);
      again.addEventListener("click", () => {
        if (confirm(`Trust worker ${w.name} again? It was set aside because ${w.set_aside}`)) {
          act("Reinstate", `/v1/workers/${encodeURIComponent(w.name)}/reinstate`, undefined, `Worker ${w.name} reinstated.`);
        }
      });
      aside.append(" ", again);
    }
    const offers = [...(w.tags || [])];
    if (w.memory_mib) offers.push(Math.round(w.memory_mib / 1024) + " GiB");
    cell(tr, offers.length ? offers.join(", ") : "–");
    const g = w.geometry;
    cell(tr, g && g.loads + g.reused > 0 ? `${g.loads} read, ${g.reused} reused` : "–");
    body.appendChild(tr);
  }
}

function drawTokens(tokens) {
  const body = $("tokens").tBodies[0];
  body.replaceChildren();
  for (const t of tokens) {
    const tr = document.createElement("tr");
    tr.dataset.token = t.id;
    cell(tr, String(t.id));
    cell(tr, t.role);
    cell(tr, t.name);
    const st = cell(tr, t.revoked ? "revoked" : "valid");
    if (!t.revoked) {
      const revoke = document.createElement("button");
      revoke.type = "button";
      revoke.className = "danger";
      revoke.textContent = "Revoke";
      revoke.setAttribute("aria-label", `Revoke token ${t.id} (${t.role} ${t.name})`);
      revoke.addEventListener("click", () => {
        if (confirm(`Revoke ${t.role} ${t.name}'s token? It is refused from its next request on.`)) {
          act("Revoke", `/v1/tokens/${t.id}/revoke`, undefined, `Token ${t.id} (${t.role} ${t.name}) revoked.`);
        }
      });
      st.append(" ", revoke);
    } else {
      st.className = "error";
    }
    body.appendChild(tr);
  }
}

// ---- one job ------------------------------------------------------------------------

function select(id) {
  state.selected = id;
  state.shown = null;
  state.frame = 0;
  state.frames = null;
  for (const t of state.thumbs) if (t && t.url) URL.revokeObjectURL(t.url);
  state.thumbs = [];
  $("strip").replaceChildren();
  $("strip").hidden = true;
  $("job").hidden = false;
  $("job-title").textContent = "Job " + id;
  for (const tr of $("jobs").tBodies[0].rows) {
    tr.className = Number(tr.dataset.job) === id ? "selected" : "";
  }
  poll();
  $("job-title").scrollIntoView({ block: "nearest" });
}

async function drawJob(j) {
  const shot = j.frame_count > 1;
  state.frames = shot ? await api("GET", `/v1/jobs/${j.id}/frames`).then((r) => r.json()) : null;
  if (state.frame >= j.frame_count) state.frame = 0;
  const facts = [
    ["State", j.state + (j.error ? ": " + j.error : "")],
    ["Frame", j.width + " × " + j.height + ", " + j.tiles_done + " / " + j.tiles_total + " tiles"],
    ["Samples", j.samples_done.toLocaleString() + " / " + j.samples_total.toLocaleString()],
    ["Passes", j.passes.join(", ") + " (" + j.passes_done + " merged)"],
    ["Rate", (j.samples_per_second / 1e6).toFixed(2) + " M samples/s"],
    ["ETA", j.state === "running" ? fmtSeconds(j.eta_seconds) : "–"],
    ["Verified", j.tile_passes_verified + " tile passes"],
    ["Failures", String(j.failures)],
  ];
  if (shot) {
    const finished = state.frames.filter((f) => f.passes_done >= j.passes.length).length;
    facts.splice(2, 0, ["Frames", `${j.frame_count}, ${finished} finished (frame ${state.frame + 1} shown)`]);
  }
  if (j.tile_passes_held) {
    facts.push(["Held", j.tile_passes_held + " tile passes wait for a second worker to check them"]);
  }
  if (j.requires && j.requires.length) facts.push(["Requires", j.requires.join(", ")]);
  if (j.max_workers) facts.push(["Workers", "at most " + j.max_workers + " at once"]);
  if (j.memory_mib) facts.push(["Memory", "about " + j.memory_mib + " MiB a worker"]);
  if (j.after && j.after.length) facts.push(["After", j.after.map((id) => "job " + id).join(", ")]);
  if (j.waiting) facts.push(["Waiting", j.waiting]);
  if (j.notice) facts.push(["Notice", j.notice]);
  if (j.webhook) facts.push(["Webhook", j.webhook]);
  const dl = $("job-facts");
  dl.replaceChildren();
  for (const [k, v] of facts) {
    const dt = document.createElement("dt");
    dt.textContent = k;
    const dd = document.createElement("dd");
    dd.textContent = v;
    dd.dataset.fact = k.toLowerCase();
    dl.append(dt, dd);
  }
  const running = j.state === "running";
  $("stop").disabled = !running || j.passes_done + 1 >= j.passes.length;
  $("cancel").disabled = !running;
  const merged = shot ? state.frames[state.frame].passes_done : j.passes_done;
  $("download-exr").setAttribute("aria-disabled", String(merged === 0));
  if (shot) await drawStrip(j);
  // A new frame when tiles or passes land, the frame shown changed, or the exposure moved.
  const key = [j.id, state.frame, j.samples_done, j.passes_done, j.state, previewQuery()].join(":");
  if (key !== state.shown) {
    state.shown = key;
    await drawFrame(j.id, shot);
  }
}

/// The query of the shown frame's preview: its exposure, and whether denoised (the
/// coordinator denoises each merged pass with Kiln's built-in denoiser when asked).
function previewQuery() {
  return `exposure=${$("exposure").value}` + ($("denoise").checked ? "&denoise=1" : "");
}

/// The path of the shown frame's `file` (result.exr or preview.png): a shot's frame's, or
/// the job's own.
function framePath(id, shot, file) {
  return shot ? `/v1/jobs/${id}/frames/${state.frame}/${file}` : `/v1/jobs/${id}/${file}`;
}

/// A shot's strip: a thumbnail per frame with its progress; a click shows that frame.
/// The buttons are made once and updated in place; thumbnails are fetched again when
/// their frame moved on, a few per poll.
async function drawStrip(j) {
  const strip = $("strip");
  strip.hidden = false;
  if (strip.children.length !== state.frames.length) {
    strip.replaceChildren();
    for (const f of state.frames) {
      const b = document.createElement("button");
      b.type = "button";
      b.className = "thumb";
      b.setAttribute("role", "listitem");
      b.setAttribute("aria-label", `Show frame ${f.index + 1}`);
      b.dataset.frame = f.index;
      const img = document.createElement("img");
      img.alt = `Frame ${f.index + 1}` + (f.scene ? ` (${f.scene})` : "");
      const bar = document.createElement("progress");
      bar.max = 1;
      const label = document.createElement("span");
      label.textContent = String(f.index + 1);
      b.append(img, bar, label);
      b.addEventListener("click", () => {
        state.frame = f.index;
        state.shown = null;
        poll();
      });
      strip.appendChild(b);
    }
  }
  let fetched = 0;
  for (const f of state.frames) {
    const b = strip.children[f.index];
    b.setAttribute("aria-pressed", String(f.index === state.frame));
    b.title = `${f.scene}: ${Math.floor(f.progress * 100)}%, ${f.passes_done} passes merged`;
    const bar = b.querySelector("progress");
    bar.value = f.progress;
    const key = [f.tiles_done, f.passes_done, f.progress, previewQuery()].join(":");
    const had = state.thumbs[f.index];
    if ((had && had.key === key) || fetched >= THUMBS_PER_POLL) continue;
    fetched++;
    try {
      const path = `/v1/jobs/${j.id}/frames/${f.index}/preview.png?${previewQuery()}`;
      const blob = await (await api("GET", path)).blob();
      if (state.selected !== j.id) return;
      if (had && had.url) URL.revokeObjectURL(had.url);
      const url = URL.createObjectURL(blob);
      state.thumbs[f.index] = { key, url };
      b.querySelector("img").src = url;
    } catch (e) {
      say(`Cannot load frame ${f.index + 1}: ` + e.message);
    }
  }
}

async function drawFrame(id, shot) {
  try {
    const r = await api("GET", framePath(id, shot, `preview.png?${previewQuery()}`));
    const blob = await r.blob();
    if (state.selected !== id) return;
    const url = URL.createObjectURL(blob);
    const img = $("frame");
    img.src = url;
    img.dataset.job = id;
    img.dataset.frame = state.frame;
    if (state.frameUrl) URL.revokeObjectURL(state.frameUrl);
    state.frameUrl = url;
  } catch (e) {
    say("Cannot load the frame: " + e.message);
  }
}

async function act(what, path, body, done) {
  try {
    await api("POST", path, body);
    say(done);
    poll();
  } catch (e) {
    say(what + " failed: " + e.message);
  }
}

async function download(kind) {
  const id = state.selected;
  if (id === null) return;
  const shot = state.frames !== null;
  const file = kind === "exr" ? "result.exr" : `preview.png?${previewQuery()}`;
  const path = framePath(id, shot, file);
  const name = shot ? `job ${id} frame ${state.frame + 1}` : `job ${id}`;
  try {
    const blob = await (await api("GET", path)).blob();
    const a = document.createElement("a");
    a.href = URL.createObjectURL(blob);
    a.download = (shot ? `job-${id}-frame-${state.frame + 1}` : `job-${id}`) + `.${kind}`;
    document.body.appendChild(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 10000);
    say(`Downloaded ${name}'s ${kind.toUpperCase()}.`);
  } catch (e) {
    say("Download failed: " + e.message);
  }
}

// ---- wiring -------------------------------------------------------------------------

$("sign-in-form").addEventListener("submit", (e) => {
  e.preventDefault();
  signIn($("token").value.trim());
});
$("sign-out").addEventListener("click", signOut);
$("token-form").addEventListener("submit", async (e) => {
  e.preventDefault();
  const body = { role: $("token-role").value, name: $("token-name").value.trim() };
  try {
    const issued = await (await api("POST", "/v1/tokens", body)).json();
    $("token-secret").textContent = issued.token;
    $("token-new").hidden = false;
    $("token-name").value = "";
    say(`Token ${issued.id} issued to ${issued.role} ${issued.name}: copy it now, it is not shown again.`);
    poll();
  } catch (err) {
    say("Issue failed: " + err.message);
  }
});
$("exposure").addEventListener("input", () => {
  $("exposure-value").textContent = $("exposure").value;
  if (state.selected !== null) {
    state.shown = null;
    poll();
  }
});
$("denoise").addEventListener("change", () => {
  if (state.selected !== null) {
    state.shown = null;
    poll();
  }
});
$("stop").addEventListener("click", () =>
  act("Stop", `/v1/jobs/${state.selected}/stop`, undefined, `Job ${state.selected} ends after this pass.`),
);
$("cancel").addEventListener("click", () => {
  if (confirm(`Cancel job ${state.selected}?`)) {
    act("Cancel", `/v1/jobs/${state.selected}/cancel`, undefined, `Job ${state.selected} cancelled.`);
  }
});
$("extend-form").addEventListener("submit", (e) => {
  e.preventDefault();
  const passes = $("extend-passes")
    .value.split(",")
    .map((s) => Number(s.trim()))
    .filter((n) => n > 0);
  if (!passes.length) {
    say("Give the new passes as samples per pixel, e.g. 4096.");
    return;
  }
  act("Extend", `/v1/jobs/${state.selected}/extend`, { passes }, `Job ${state.selected} extended to ${passes.join(", ")}.`);
});
for (const kind of ["exr", "png"]) {
  $("download-" + kind).addEventListener("click", (e) => {
    e.preventDefault();
    download(kind);
  });
}

if (state.token !== null) signIn(state.token);
else $("token").focus();
