#!/usr/bin/env python3
"""The dashboard in a real browser: headless Chromium (Debian's chromium + chromium-driver) driven
by Selenium (python3-selenium), against the real coordinator and worker dashboard_test.sh started.

- the page loads; the client token typed into it is used for its API calls;
- a job submitted with `irfarm submit` appears in the jobs table, its progress text goes up and
  reaches 100% with state SUCCEEDED; a screenshot is taken mid-job (partial image shown);
- the job's image is shown: an <img> of the film's size whose pixels (read back through a canvas)
  are not black;
- its record map is shown beside it: an <img> of the film's size, black but for pixels in the
  two workers' colours (the swatches of the workers table), both present; records shown mid-job
  already, and no more than at the end (it refreshes as the job runs: a job's first tiles make
  most records, so a mid-job map may already hold them all);
- with the worker stopped, a second job's priority is set and the job cancelled with the page's
  buttons; `irfarm status --json` then shows the new priority and JOB_STATE_CANCELLED.

Usage: dashboard_browser_test.py URL TOKEN BIN COORDINATOR SCENE WORKER_PIDS CHROME DRIVER SHOT
(WORKER_PIDS: the two workers' process ids, comma-separated)
"""
import json
import os
import signal
import subprocess
import sys
import time

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By

URL, TOKEN, BIN, COORD, SCENE, WORKER, CHROME, DRIVER, SHOT = sys.argv[1:10]
RES = 320  # the first job's film, square
WORKERS = [int(p) for p in WORKER.split(",")]
env = dict(os.environ, IRFARM_TOKEN=TOKEN)


def irfarm(*args):
    return subprocess.run([os.path.join(BIN, "irfarm")] + list(args) + ["--coordinator", COORD],
                          env=env, check=True, capture_output=True, text=True).stdout


def wait_for(what, fn, timeout=120):
    end = time.time() + timeout
    while time.time() < end:
        try:
            v = fn()
            if v:
                return v
        except Exception:  # element not there yet, or replaced by the next poll
            pass
        time.sleep(0.1)
    raise AssertionError("timed out waiting for " + what)


# Pixel colours of <img id=ID> read back through a canvas (blob URL: same origin, so the canvas
# is not tainted): [width, height, {"r,g,b": count}], or None until it shows `job`.
COLOURS_JS = """
    const img = document.getElementById(arguments[0]);
    if (!img.complete || img.naturalWidth == 0 || img.dataset.job != arguments[1]) return null;
    const c = document.createElement('canvas');
    c.width = img.naturalWidth; c.height = img.naturalHeight;
    const g = c.getContext('2d'); g.drawImage(img, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    const n = {};
    for (let i = 0; i < d.length; i += 4) {
      const k = d[i] + ',' + d[i + 1] + ',' + d[i + 2];
      n[k] = (n[k] || 0) + 1;
    }
    return [img.naturalWidth, img.naturalHeight, n];
"""


def map_colours(driver, job):
    """The record map's colour counts and the workers' swatch colours {name: "r,g,b"}."""
    m = wait_for("record map", lambda: driver.execute_script(COLOURS_JS, "record-map", job),
                 timeout=10)
    # Read in one script: the page rebuilds the workers table at every poll, so elements found
    # one call earlier can be gone (StaleElementReferenceException, seen in a loaded run).
    swatches = driver.execute_script("""
        const out = {};
        for (const td of document.querySelectorAll('#workers tbody tr td.name')) {
          const sw = td.querySelector('.swatch');
          if (sw) out[td.textContent.trim()] = sw.getAttribute('data-rgb');
        }
        return out;""")
    return m, swatches


def row_text(driver, job, cls):
    return driver.find_element(By.CSS_SELECTOR, "#job-%s .%s" % (job, cls)).text


opts = webdriver.ChromeOptions()
opts.binary_location = CHROME
for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
          "--window-size=1280,1000"):
    opts.add_argument(a)
driver = webdriver.Chrome(service=Service(DRIVER), options=opts)
try:
    driver.get(URL)
    assert driver.title == "irfarm dashboard", driver.title
    print("ok: page loaded: %s" % driver.title)
    driver.find_element(By.ID, "token").send_keys(TOKEN)
    driver.find_element(By.ID, "use-token").click()

    # Fixed record rays: the default balance may pick fewer, and then the job can finish between
    # two polls with no mid-job state to see. Up to 256 spp and a = 0.05 for the same reason: at
    # the defaults the job took about 3 s and the page saw 28%, 72%, 100% (no poll within
    # 30-70%); then about 8 s, five or more progress values. At 160 x 160 it later took about 2 s
    # (adaptive sampling stops early) and the page saw 27%, 77%, 100% in one run of three: now
    # 320 x 320 in tiles of 32 (the same 100 tiles, four times the pixels).
    job = irfarm("submit", SCENE, "-Dresx=%d" % RES, "-Dresy=%d" % RES, "--tile-size", "32",
                 "--record-rays", "1536", "--spp", "256", "--accuracy", "0.05", "-q").strip()
    wait_for("job row", lambda: driver.find_element(By.ID, "job-" + job))
    print("ok: submitted %s appears in the jobs table" % job)
    driver.find_element(By.ID, "job-" + job).click()  # show its image
    seen = []
    shot = False
    end = time.time() + 120
    while time.time() < end:
        try:
            pct = int(row_text(driver, job, "pct").rstrip("%"))
            state = row_text(driver, job, "state")
        except Exception:
            time.sleep(0.05)
            continue
        if not seen or seen[-1] != pct:
            seen.append(pct)
        if not shot and 30 <= pct <= 70 and state == "RUNNING":
            time.sleep(1.1)  # one more poll: the image of these tiles
            driver.save_screenshot(SHOT)
            mid_map, _ = map_colours(driver, job)
            shot = True
            print("ok: mid-job screenshot at %d%% saved to %s" % (pct, SHOT))
        if state == "SUCCEEDED" and pct == 100:
            break
        time.sleep(0.1)
    print("progress seen: %s" % seen)
    assert seen and seen[-1] == 100 and seen == sorted(seen) and len(seen) >= 3, seen
    assert row_text(driver, job, "state") == "SUCCEEDED"
    print("ok: progress went up to 100%%, state SUCCEEDED (%d distinct values)" % len(seen))
    assert shot, "no screenshot mid-job"

    # The image: the film's size, and not black. Read back through a canvas (blob URL: same
    # origin, so the canvas is not tainted); wait for the poll after the last tile.
    time.sleep(1.5)
    info = wait_for("image", lambda: driver.execute_script("""
        const img = document.getElementById('image');
        if (!img.complete || img.naturalWidth == 0 || img.dataset.job != arguments[0]) return null;
        const c = document.createElement('canvas');
        c.width = img.naturalWidth; c.height = img.naturalHeight;
        const g = c.getContext('2d'); g.drawImage(img, 0, 0);
        const d = g.getImageData(0, 0, c.width, c.height).data;
        let sum = 0, black = 0;
        for (let i = 0; i < d.length; i += 4) {
          const v = d[i] + d[i + 1] + d[i + 2];
          sum += v; if (v == 0) black++;
        }
        return [img.naturalWidth, img.naturalHeight, sum / (d.length / 4) / 3, black / (d.length / 4)];
        """, job))
    w, h, mean, black = info
    print("MEASURED shown image %dx%d, mean 8-bit value %.1f, black pixels %.3f" % (w, h, mean, black))
    assert (w, h) == (RES, RES), info
    # The film has a thin black frame (the camera sees past the box: ~5%); a blank or half-done
    # image would be far darker.
    assert mean > 20 and black < 0.2, info
    print("ok: the job's image is shown")

    # The record map: the film's size, black but for the two workers' colours, both present.
    (mw, mh, colours), swatches = map_colours(driver, job)
    print("MEASURED record map %dx%d, colours %s; workers' swatches %s; mid-job %s" %
          (mw, mh, colours, swatches, mid_map[2]))
    assert (mw, mh) == (RES, RES), (mw, mh)
    assert sorted(swatches) == ["w1", "w2"] and swatches["w1"] != swatches["w2"], swatches
    counts = {name: colours.get(rgb, 0) for name, rgb in swatches.items()}
    others = {k: v for k, v in colours.items() if k != "0,0,0" and k not in swatches.values()}
    assert others == {}, others
    assert counts["w1"] > 0 and counts["w2"] > 0, counts
    mid = sum(v for k, v in mid_map[2].items() if k != "0,0,0")
    # Records are made mostly by the first tiles (later ones find the shared cache covering
    # them), so the mid-job map may already hold every record: at most as many, not fewer.
    assert 0 < mid <= sum(counts.values()), (mid, counts)
    print("ok: the record map shows records of both workers in their colours (%s), %d mid-job" %
          (counts, mid))

    # Priority and cancel from the page, with the worker stopped so the job stays queued.
    for w in WORKERS:
        os.kill(w, signal.SIGSTOP)
    try:
        j2 = irfarm("submit", SCENE, "-Dresx=64", "-Dresy=64", "-q").strip()
        wait_for("second job row", lambda: driver.find_element(By.ID, "job-" + j2))
        # Typed over at least one poll: the page must not reset the field while it has focus.
        prio = driver.find_element(By.CSS_SELECTOR, "#job-%s input.prio" % j2)
        prio.click()
        prio.clear()
        prio.send_keys("7")
        time.sleep(1.5)
        prio.send_keys("3")
        driver.find_element(By.CSS_SELECTOR, "#job-%s button.set-priority" % j2).click()
        wait_for("priority 73", lambda: json.loads(irfarm("status", j2, "--json"))["priority"] == 73,
                 timeout=10)
        print("ok: priority set from the page")
        wait_for("cancel click", lambda: driver.find_element(
            By.CSS_SELECTOR, "#job-%s button.cancel" % j2).click() or True, timeout=10)
        wait_for("CANCELLED in the page", lambda: row_text(driver, j2, "state") == "CANCELLED",
                 timeout=10)
        st = json.loads(irfarm("status", j2, "--json"))["state"]
        assert st == "JOB_STATE_CANCELLED", st
        print("ok: cancel from the page: %s is %s" % (j2, st))
    finally:
        for w in WORKERS:
            os.kill(w, signal.SIGCONT)
finally:
    driver.quit()
print("PASS")
