#!/usr/bin/env python3
"""Drives Kiln's farm dashboard in headless Chromium (Selenium, the system's chromium and
chromedriver), as tests/dashboard.rs asks: signs in with the token from the keyboard (and
prints "dashboard: signed in", the test's cue to start the worker), watches a job progress
through its passes to done while its frame's pixels change, its ETA and the worker's
current tile show, moves the exposure, toggles the denoised frame, downloads the EXR, extends the job by its form,
stops a second job after its pass in progress and downloads its PNG, cancels a third,
shows each job's thumbnail and the workers' pools by tag, a shot's strip of frame thumbnails with their progress, picks its third frame and
downloads that frame's EXR, issues a token and revokes a worker's credential in the tokens
panel, signs in again as a submitter who sees only its own job and no workers or tokens,
checks a narrow screen, a frame that is not blank and a console
without errors. Prints what
it saw; exits 1 with the reason on any failure."""

import argparse
import struct
import sys
import time
import zlib

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys


def fail(why):
    print(f"dashboard: FAILED: {why}", flush=True)
    sys.exit(1)


def wait_for(what, predicate, limit=60.0):
    start = time.time()
    while True:
        try:
            value = predicate()
        except Exception:  # the page is redrawing: ask again
            value = None
        if value:
            return value
        if time.time() - start > limit:
            fail(f"timed out after {limit:.0f} s waiting for {what}")
        time.sleep(0.05)


def png_pixels(png):
    """The decompressed scanlines of a PNG (filter bytes included): enough to tell a blank
    image from one with content, without an imaging library."""
    if png[:8] != b"\x89PNG\r\n\x1a\n":
        fail("the screenshot is not a PNG")
    pos, idat = 8, b""
    while pos < len(png):
        length, kind = struct.unpack(">I4s", png[pos : pos + 8])
        if kind == b"IDAT":
            idat += png[pos + 8 : pos + 8 + length]
        pos += 12 + length
    return zlib.decompress(idat)


def fact(driver, name):
    """A fact of the job panel, read in one script (the panel is redrawn every second, so
    an element found first and read later may be gone)."""
    return driver.execute_script(
        "const d = document.querySelector(`#job-facts dd[data-fact='${arguments[0]}']`);"
        "return d ? d.textContent : '';",
        name,
    )


# The frame's pixels as the page shows them: a hash, the mean of the 8-bit channels and how
# many distinct colours (up to 1000), drawn through a canvas (the image is a same-origin
# object URL, so the canvas may be read). None while the image is loading.
FRAME_PIXELS = """
const img = document.getElementById('frame');
if (!img.complete || !img.naturalWidth) return null;
const c = document.createElement('canvas');
c.width = img.naturalWidth; c.height = img.naturalHeight;
const g = c.getContext('2d');
g.drawImage(img, 0, 0);
const d = g.getImageData(0, 0, c.width, c.height).data;
let h = 0, sum = 0;
const colours = new Set();
for (let i = 0; i < d.length; i += 4) {
  h = (Math.imul(h, 31) + (d[i] << 16 | d[i + 1] << 8 | d[i + 2])) | 0;
  sum += d[i] + d[i + 1] + d[i + 2];
  if (colours.size < 1000) colours.add(d[i] << 16 | d[i + 1] << 8 | d[i + 2]);
}
return [h, sum / (3 * d.length / 4), colours.size];
"""


def frame_pixels(driver):
    return driver.execute_script(FRAME_PIXELS)


def cells(driver, table, column):
    """The text of one column of a table's rows, read in one script."""
    return driver.execute_script(
        f"return [...document.querySelectorAll('#{table} tbody tr td:nth-child({column})')].map(c => c.textContent)"
    )


def press(driver, what, selector, key=None):
    """Finds and presses (clicks, or sends `key` to) the element `selector` in one go, again
    if the list it is in was redrawn between the two (the page redraws its tables every
    second)."""

    def go():
        element = driver.find_element(By.CSS_SELECTOR, selector)
        if key is None:
            element.click()
        else:
            element.send_keys(key)
        return True

    wait_for(what, go)


def show_job(driver, job):
    press(driver, f"job {job}'s button", f'button[aria-label="Show job {job}"]')
    wait_for(f"job {job}'s panel", lambda: driver.find_element(By.ID, "job-title").text == f"Job {job}")
    wait_for(f"job {job}'s facts", lambda: fact(driver, "state") != "")


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--url", required=True)
    p.add_argument("--token", required=True)
    p.add_argument("--watch", type=int, required=True, help="the job to follow to done")
    p.add_argument("--stop", type=int, required=True, help="the job to stop after its first pass")
    p.add_argument("--cancel", type=int, required=True, help="the job to cancel")
    p.add_argument("--shot", type=int, required=True, help="a shot of three frames")
    p.add_argument("--submitter-token", required=True, help="a submitter's token")
    p.add_argument("--submitter-job", type=int, required=True, help="the submitter's job")
    p.add_argument("--revoke", type=int, required=True, help="a worker credential's id to revoke")
    p.add_argument("--screenshot", required=True)
    p.add_argument("--shot-screenshot", required=True, help="where the shot's view is saved")
    p.add_argument("--chromium", default="/usr/bin/chromium")
    p.add_argument("--chromedriver", default="/usr/bin/chromedriver")
    a = p.parse_args()

    options = webdriver.ChromeOptions()
    options.binary_location = a.chromium
    for arg in ["--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1280,1000"]:
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(a.chromedriver), options=options)
    try:
        run(driver, a)
    finally:
        driver.quit()


def run(driver, a):
    driver.get(a.url + "/")
    if driver.title != "Kiln farm":
        fail(f"the page's title is {driver.title!r}")
    # A wrong token is refused, saying so.
    token = wait_for("the token field", lambda: driver.find_element(By.ID, "token"))
    token.send_keys("not-the-token" + Keys.ENTER)
    wait_for("the refusal", lambda: "not the coordinator" in driver.find_element(By.ID, "sign-in-error").text)
    # Signed in from the keyboard.
    token.clear()
    token.send_keys(a.token + Keys.ENTER)
    wait_for("the farm view", lambda: driver.find_element(By.ID, "farm").is_displayed())
    print("dashboard: signed in", flush=True)

    # Stop the second job (below the watched one in priority, so not started yet) after
    # its pass in progress, its first: its schedule is cut to that pass.
    show_job(driver, a.stop)
    stop = wait_for("an enabled stop button", lambda: (b := driver.find_element(By.ID, "stop")).is_enabled() and b)
    stop.send_keys(Keys.ENTER)
    wait_for("the stop", lambda: "ends after this pass" in driver.find_element(By.ID, "message").text)
    wait_for("the schedule cut to one pass", lambda: fact(driver, "passes").startswith("8 ("))
    print(f"dashboard: job {a.stop} will end after its first pass", flush=True)

    # The job to watch, chosen by keyboard.
    press(driver, f"job {a.watch} in the list", f'button[aria-label="Show job {a.watch}"]', Keys.ENTER)
    wait_for("the job panel", lambda: driver.find_element(By.ID, "job").is_displayed())
    # What the job needs of a worker, and what the workers offer (their machine's memory).
    memory = wait_for("the job's memory", lambda: fact(driver, "memory"))
    if not (memory.startswith("about ") and memory.endswith(" MiB a worker")):
        fail(f"the job's memory fact says {memory!r}")
    wait_for("a worker's memory", lambda: any("GiB" in c for c in cells(driver, "workers", 7)))
    frame = driver.find_element(By.ID, "frame")
    wait_for("a frame", lambda: frame_pixels(driver))
    seen_passes, pixels, states, etas, rendering = set(), [], [], set(), set()
    start = time.time()
    while True:
        state = fact(driver, "state")
        passes = fact(driver, "passes")
        seen_passes.add(passes)
        etas.add(fact(driver, "eta"))
        rendering.update(cells(driver, "workers", 2))
        now = frame_pixels(driver)
        if now and (not pixels or pixels[-1][0] != now[0]):
            pixels.append(now)
        if not states or states[-1] != state:
            states.append(state)
        if state.startswith("done"):
            break
        if state.startswith(("failed", "cancelled")):
            fail(f"job {a.watch} ended {state}")
        if time.time() - start > 240:
            fail(f"job {a.watch} did not finish: {state}, {passes}")
        time.sleep(0.1)
    # The frame drawn after the job ended.
    final = wait_for(
        "the final frame",
        lambda: (f := frame_pixels(driver)) and f[0] != pixels[0][0] and f,
    )
    if pixels[-1][0] != final[0]:
        pixels.append(final)
    print(
        f"dashboard: job {a.watch} went {' -> '.join(states)}; passes seen: {sorted(seen_passes)}; "
        f"{len(pixels)} different frames; ETAs seen: {sorted(etas)}",
        flush=True,
    )
    if len(seen_passes) < 2:
        fail(f"the job's passes never changed on screen: {seen_passes}")
    if len(pixels) < 3:
        fail(f"the frame's pixels changed {len(pixels) - 1} time(s) over four passes")
    if final[1] < 4 or final[2] < 50:
        fail(f"the finished frame looks blank: mean {final[1]:.1f} of 255, {final[2]} colours")
    if not any(e.endswith((" s", " min", " h")) for e in etas):
        fail(f"no ETA was shown while the job ran: {etas}")
    if not any(r.startswith(f"job {a.watch} tile ") for r in rendering):
        fail(f"the workers table never showed what the worker rendered: {rendering}")
    heard = cells(driver, "workers", 5)
    if not heard or not all(h.endswith(" ago") for h in heard):
        fail(f"the workers table does not say when each worker was last heard from: {heard}")
    final_passes = fact(driver, "passes")
    if "(4 merged)" not in final_passes:
        fail(f"the finished job shows {final_passes!r}")
    if not driver.find_element(By.ID, "cancel").get_attribute("disabled"):
        fail("a finished job can still be cancelled")

    # Exposure by keyboard: the frame is drawn again, brighter.
    before = frame_pixels(driver)
    slider = driver.find_element(By.ID, "exposure")
    slider.send_keys(Keys.ARROW_RIGHT, Keys.ARROW_RIGHT)
    wait_for("the exposure to change", lambda: driver.find_element(By.ID, "exposure-value").text == "1")
    brighter = wait_for(
        "a frame at the new exposure",
        lambda: (f := frame_pixels(driver)) and f[0] != before[0] and f,
    )
    if not brighter[1] > before[1]:
        fail(f"one stop up, the frame's mean went from {before[1]:.1f} to {brighter[1]:.1f}")
    print(f"dashboard: exposure moved to 1 stop, mean {before[1]:.1f} -> {brighter[1]:.1f}", flush=True)

    # The Denoised box, by keyboard: the coordinator's denoised frame, another picture as
    # bright as the raw one; unticked, the raw frame again.
    raw_frame = frame_pixels(driver)
    driver.find_element(By.ID, "denoise").send_keys(Keys.SPACE)
    denoised = wait_for(
        "the denoised frame",
        lambda: (f := frame_pixels(driver)) and f[0] != raw_frame[0] and f,
    )
    if abs(denoised[1] - raw_frame[1]) > 0.1 * raw_frame[1]:
        fail(f"the denoised frame's mean is {denoised[1]:.1f}, the raw one's {raw_frame[1]:.1f}")
    if "Cannot load" in driver.find_element(By.ID, "message").text:
        fail(driver.find_element(By.ID, "message").text)
    driver.find_element(By.ID, "denoise").send_keys(Keys.SPACE)
    wait_for("the raw frame again", lambda: (f := frame_pixels(driver)) and f[0] == raw_frame[0])
    print(f"dashboard: denoised, mean {raw_frame[1]:.1f} -> {denoised[1]:.1f}", flush=True)

    # Download the EXR: fetched with the token, handed to the browser.
    driver.find_element(By.ID, "download-exr").send_keys(Keys.ENTER)
    wait_for("the download", lambda: "Downloaded job" in driver.find_element(By.ID, "message").text)

    # The screenshot (the finished job, its frame and facts) is not blank.
    shot = driver.get_screenshot_as_png()
    with open(a.screenshot, "wb") as f:
        f.write(shot)
    raw = png_pixels(shot)
    distinct = len(set(raw))
    if distinct < 64:
        fail(f"the screenshot looks blank ({distinct} distinct byte values)")
    print(f"dashboard: screenshot {len(shot)} bytes, {distinct} distinct byte values", flush=True)

    # Extend the finished job by its form: it runs again, to a fifth pass.
    show_job(driver, a.watch)
    field = driver.find_element(By.ID, "extend-passes")
    field.send_keys("1024" + Keys.ENTER)
    wait_for("the extension", lambda: "extended to 1024" in driver.find_element(By.ID, "message").text)
    wait_for(
        f"job {a.watch} done at 1024 samples",
        lambda: fact(driver, "state").startswith("done") and "(5 merged)" in fact(driver, "passes"),
        limit=240,
    )
    print(f"dashboard: job {a.watch} extended to 1024 and done again", flush=True)

    # The stopped job ran its one pass after the watched one: done, whole; its PNG.
    show_job(driver, a.stop)
    wait_for(
        f"job {a.stop} done after one pass",
        lambda: fact(driver, "state").startswith("done") and fact(driver, "passes") == "8 (1 merged)",
        limit=240,
    )
    driver.find_element(By.ID, "download-png").send_keys(Keys.ENTER)
    wait_for(
        "the PNG download",
        lambda: f"Downloaded job {a.stop}'s PNG" in driver.find_element(By.ID, "message").text,
    )
    print(f"dashboard: job {a.stop} done after its first pass; PNG downloaded", flush=True)

    # Cancel the third job, confirming the dialog.
    show_job(driver, a.cancel)
    cancel = wait_for("an enabled cancel button", lambda: (b := driver.find_element(By.ID, "cancel")).is_enabled() and b)
    cancel.click()
    driver.switch_to.alert.accept()
    wait_for(f"job {a.cancel} cancelled", lambda: fact(driver, "state").startswith("cancelled"))
    row_state = wait_for(
        "the job list to say cancelled",
        lambda: (t := driver.execute_script(
            "const c = document.querySelector(`#jobs tr[data-job='${arguments[0]}'] td:nth-child(3)`);"
            "return c ? c.textContent : '';",
            a.cancel,
        )) == "cancelled" and t,
    )
    if row_state != "cancelled":
        fail(f"the job list says {row_state!r}")
    print(f"dashboard: job {a.cancel} cancelled", flush=True)

    # A shot: a strip of three thumbnails, each frame finished; its third frame shown and
    # downloaded; the worker's meshes counted.
    show_job(driver, a.shot)
    thumbs = "#strip button.thumb"
    wait_for("the shot's strip", lambda: len(driver.find_elements(By.CSS_SELECTOR, thumbs)) == 3)
    wait_for(
        "every frame finished, its thumbnail drawn",
        lambda: driver.execute_script(
            f"return [...document.querySelectorAll('{thumbs}')].every("
            "b => b.querySelector('progress').value === 1 && b.querySelector('img').naturalWidth > 0)"
        ),
        limit=120,
    )
    driver.find_element(By.CSS_SELECTOR, 'button[aria-label="Show frame 3"]').click()
    wait_for("frame 3 shown", lambda: driver.find_element(By.ID, "frame").get_attribute("data-frame") == "2")
    frames = wait_for("the frames fact", lambda: (t := fact(driver, "frames")) and "frame 3 shown" in t and t)
    if not frames.startswith("3, 3 finished"):
        fail(f"the shot's frames fact says {frames!r}")
    wait_for("frame 3's pixels", lambda: frame_pixels(driver))
    driver.find_element(By.ID, "download-exr").send_keys(Keys.ENTER)
    wait_for(
        "frame 3's EXR",
        lambda: f"Downloaded job {a.shot} frame 3's EXR" in driver.find_element(By.ID, "message").text,
    )
    with open(a.shot_screenshot, "wb") as f:
        f.write(driver.get_screenshot_as_png())
    meshes = cells(driver, "workers", 8)
    if not any(m.endswith(" reused") for m in meshes):
        fail(f"the workers table does not count the meshes read and reused: {meshes}")
    print(f"dashboard: shot {a.shot}: 3 frames in the strip, frame 3 shown and downloaded; meshes {meshes}", flush=True)

    # Every job in the list has its thumbnail; the workers' pools are counted by tag.
    wait_for(
        "a thumbnail on every job",
        lambda: driver.execute_script(
            "const t = [...document.querySelectorAll('#jobs tbody img.job-thumb')];"
            "return t.length >= 5 && t.every(i => i.complete && i.naturalWidth > 0);"
        ),
    )
    pools = wait_for("the pools", lambda: driver.find_element(By.ID, "pools").text)
    if not pools.startswith("Pools: big-mem ") or not pools.endswith("/1 busy"):
        fail(f"the pools read {pools!r}")
    print(f"dashboard: every job has its thumbnail; {pools}", flush=True)

    # Workers are listed with what they did.
    done = cells(driver, "workers", 3)
    if not done or all(d in ("", "0") for d in done):
        fail(f"the workers table does not show the tiles done: {done}")

    # A narrow screen: nothing wider than the window; the frame fits.
    driver.set_window_size(390, 844)
    time.sleep(0.3)
    over = driver.execute_script("return document.documentElement.scrollWidth - window.innerWidth")
    if over > 1:
        fail(f"on a narrow screen the page is {over} px wider than the window")
    fw = driver.execute_script("return document.getElementById('frame').getBoundingClientRect().width")
    iw = driver.execute_script("return window.innerWidth")
    if fw > iw:
        fail(f"on a narrow screen the frame ({fw} px) is wider than the window ({iw} px)")
    print("dashboard: narrow screen fits", flush=True)

    # The admin's tokens panel: issue a submitter's token, revoke a worker's credential.
    driver.set_window_size(1280, 1000)
    wait_for("the tokens panel", lambda: driver.find_element(By.ID, "tokens-panel").is_displayed())
    driver.find_element(By.ID, "token-role").send_keys("submitter")
    name = driver.find_element(By.ID, "token-name")
    name.send_keys("carol" + Keys.ENTER)
    secret = wait_for("the new token", lambda: driver.find_element(By.ID, "token-secret").text)
    if not secret.startswith("kiln-"):
        fail(f"the new token reads {secret!r}")
    wait_for("carol's token listed", lambda: any(c == "carol" for c in cells(driver, "tokens", 3)))
    press(driver, "the worker's revoke button", f'button[aria-label^="Revoke token {a.revoke} "]')
    driver.switch_to.alert.accept()
    wait_for(
        "the credential revoked",
        lambda: driver.execute_script(
            f"const c = document.querySelector('#tokens tr[data-token=\"{a.revoke}\"] td:nth-child(4)');"
            "return c ? c.textContent : '';"
        ) == "revoked",
    )
    print(f"dashboard: token issued to carol; worker credential {a.revoke} revoked", flush=True)

    # A submitter: its own job only, no workers, no tokens.
    driver.find_element(By.ID, "sign-out").click()
    token = wait_for("the token field", lambda: (t := driver.find_element(By.ID, "token")).is_displayed() and t)
    token.send_keys(a.submitter_token + Keys.ENTER)
    wait_for("the submitter's view", lambda: "(submitter)" in driver.find_element(By.ID, "who").text)
    listed = wait_for(
        "the submitter's jobs",
        lambda: driver.execute_script("return [...document.querySelectorAll('#jobs tbody tr')].map(r => Number(r.dataset.job))"),
    )
    if listed != [a.submitter_job]:
        fail(f"the submitter sees jobs {listed}, not only its own {a.submitter_job}")
    if driver.find_element(By.ID, "workers-panel").is_displayed() or driver.find_element(By.ID, "tokens-panel").is_displayed():
        fail("a submitter sees the workers or the tokens")
    show_job(driver, a.submitter_job)
    print(f"dashboard: submitter sees only job {a.submitter_job}", flush=True)

    # No console errors.
    errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    if errors:
        fail(f"console errors: {errors}")
    print("dashboard: ok", flush=True)


if __name__ == "__main__":
    main()
