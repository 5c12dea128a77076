#!/usr/bin/env python3
"""Drives Kiln's farm dashboard in headless Chromium (Selenium, the system's chromium and
chromedriver), as tests/dashboard.rs asks: signs in with the token from the keyboard,
watches a job progress through its passes to done while its frame changes, moves the
exposure, cancels another job, checks a narrow screen, a screenshot that is not blank and
a console without errors. Prints what it saw; exits 1 with the reason on any failure."""

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


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--url", required=True)
    p.add_argument("--token", required=True)
    p.add_argument("--watch", type=int, required=True, help="the job to follow to done")
    p.add_argument("--cancel", type=int, required=True, help="the job to cancel")
    p.add_argument("--screenshot", required=True)
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

    # The job to watch, chosen by keyboard.
    show = wait_for(
        f"job {a.watch} in the list",
        lambda: driver.find_element(By.CSS_SELECTOR, f'button[aria-label="Show job {a.watch}"]'),
    )
    show.send_keys(Keys.ENTER)
    wait_for("the job panel", lambda: driver.find_element(By.ID, "job").is_displayed())
    frame = driver.find_element(By.ID, "frame")
    wait_for("a frame", lambda: frame.get_attribute("src").startswith("blob:") and frame.get_attribute("naturalWidth") != "0")
    seen_passes, frames, states = set(), set(), []
    start = time.time()
    while True:
        state = fact(driver, "state")
        passes = fact(driver, "passes")
        seen_passes.add(passes)
        src = frame.get_attribute("src")
        frames.add(src)
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
    wait_for("the final frame", lambda: frame.get_attribute("src") not in frames or len(frames) > 1)
    frames.add(frame.get_attribute("src"))
    print(f"dashboard: job {a.watch} went {' -> '.join(states)}; passes seen: {sorted(seen_passes)}; {len(frames)} frames", flush=True)
    if len(seen_passes) < 2:
        fail(f"the job's passes never changed on screen: {seen_passes}")
    if len(frames) < 2:
        fail("the frame never changed")
    final_passes = fact(driver, "passes")
    if "(4 merged)" not in final_passes:
        fail(f"the finished job shows {final_passes!r}")
    if not driver.find_element(By.ID, "cancel").get_attribute("disabled"):
        fail("a finished job can still be cancelled")

    # Exposure by keyboard: the frame is drawn again, brighter.
    before = frame.get_attribute("src")
    slider = driver.find_element(By.ID, "exposure")
    slider.send_keys(Keys.ARROW_RIGHT, Keys.ARROW_RIGHT)
    wait_for("the exposure to change", lambda: driver.find_element(By.ID, "exposure-value").text == "1")
    wait_for("a frame at the new exposure", lambda: frame.get_attribute("src") != before)
    print("dashboard: exposure moved to 1 stop, frame redrawn", flush=True)

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

    # Cancel the other job, confirming the dialog.
    driver.find_element(By.CSS_SELECTOR, f'button[aria-label="Show job {a.cancel}"]').click()
    wait_for(f"job {a.cancel}'s panel", lambda: driver.find_element(By.ID, "job-title").text == f"Job {a.cancel}")
    cancel = wait_for("an enabled cancel button", lambda: (b := driver.find_element(By.ID, "cancel")).is_enabled() and b)
    cancel.click()
    driver.switch_to.alert.accept()
    wait_for(f"job {a.cancel} cancelled", lambda: fact(driver, "state").startswith("cancelled"))
    row_state = wait_for(
        "the job list to say cancelled",
        lambda: (t := driver.execute_script(
            "const c = document.querySelector(`#jobs tr[data-job='${arguments[0]}'] td:nth-child(2)`);"
            "return c ? c.textContent : '';",
            a.cancel,
        )) == "cancelled" and t,
    )
    if row_state != "cancelled":
        fail(f"the job list says {row_state!r}")
    print(f"dashboard: job {a.cancel} cancelled", flush=True)

    # Workers are listed with what they did.
    done = driver.execute_script(
        "return [...document.querySelectorAll('#workers tbody tr td:nth-child(3)')].map(c => c.textContent)"
    )
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

    # No console errors.
    errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    if errors:
        fail(f"console errors: {errors}")
    print("dashboard: ok", flush=True)


if __name__ == "__main__":
    main()
