"""A participant in headless Chromium runs a whole `touchc study run` session.

Usage: python study_page.py TOUCHC PTY_SLEEVE [SCREENSHOT_DIR]

The real `touchc` binary plays the example plan (examples/study/emoji.toml: acclimation,
three rounds, the Self-Assessment Manikin round) on the in-memory sleeve behind a
pseudo-terminal (PTY_SLEEVE: tests/examples/pty_sleeve.rs). The participant reads the
prompts, moves sliders with the keyboard (and meets the page's refusal of a tie), clicks
manikins; the session is killed mid-round, resumed in the same browser, and completed.
Then the log and `touchc study report` are checked. With SCREENSHOT_DIR, screenshots of
the page are saved there (docs/study/).
"""

import json
import random
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys

ROOT = Path(__file__).resolve().parents[2]
touchc, pty_sleeve = sys.argv[1], sys.argv[2]
shots = Path(sys.argv[3]) if len(sys.argv) > 3 else None
work = Path(tempfile.mkdtemp())
rng = random.Random(37)


def start(plan, port, log, resume):
    args = [touchc, "study", "run", str(plan), "--participant", "b1", "--port", port,
            "--http-port", "0", "--log", str(log)] + (["--resume"] if resume else [])
    p = subprocess.Popen(args, stderr=subprocess.PIPE, text=True)
    first = p.stderr.readline()
    url = next(w for w in first.split() if w.startswith("http://"))
    threading.Thread(target=lambda: [None for _ in p.stderr], daemon=True).start()
    return p, url


def shot(driver, name):
    if shots:
        shots.mkdir(parents=True, exist_ok=True)
        driver.save_screenshot(str(shots / name))


def text(driver):
    return driver.find_element(By.ID, "main").text


def classify(driver):
    sliders = driver.find_elements(By.CSS_SELECTOR, "input[type=range]")
    send = driver.find_element(By.ID, "send")
    assert send.get_attribute("disabled") is not None, ("nothing moved: Next is disabled", send.get_attribute("outerHTML"), [x.get_attribute("value") for x in sliders])
    a, b = rng.sample(range(len(sliders)), 2)
    # A tie for the largest value: the page refuses it.
    sliders[a].send_keys(Keys.END)
    sliders[b].send_keys(Keys.END)
    assert send.get_attribute("disabled") is not None, "a tie must disable Next"
    assert "share the largest" in driver.find_element(By.ID, "err").text
    sliders[b].send_keys(Keys.PAGE_DOWN)
    for i, s in enumerate(sliders):
        if i not in (a, b):
            for _ in range(rng.randrange(0, 30)):
                s.send_keys(Keys.ARROW_RIGHT)
    assert send.get_attribute("disabled") is None, "a unique largest value enables Next"
    return send


def manikins(driver):
    v, a = rng.randint(1, 9), rng.randint(1, 9)
    driver.find_element(By.ID, f"valence{v}").click()
    driver.find_element(By.ID, f"arousal{a}").click()
    return driver.find_element(By.ID, "send")


def participant(driver, stop_after=None):
    """Answers until the session is done (or `stop_after` answers); returns the count."""
    answered, seen, until = 0, set(), time.time() + 300
    while time.time() < until:
        try:
            body = text(driver)
        except Exception:
            time.sleep(0.05)
            continue
        if "Thank you" in body:
            return answered
        starts = driver.find_elements(By.ID, "start")
        if starts:
            shot(driver, "page-intro.png")
            starts[0].click()
            time.sleep(0.3)
            continue
        # One snapshot of the page: what it asks and its first line. An answer page
        # stays until it is answered; a stale one (answered, not yet replaced) is seen.
        kind, key = driver.execute_script(
            "const m = document.getElementById('main');"
            "const k = m.querySelector('input[type=range]') ? 'range' : m.querySelector('input[type=radio]') ? 'radio' : '';"
            "return [k, m.innerText.split('\\n')[0]];")
        if not kind or key in seen:
            time.sleep(0.05)
            continue
        ranges = kind == "range"
        if ranges:
            send = classify(driver)
            if answered == 2:
                shot(driver, "page-classify.png")
        else:
            send = manikins(driver)
            shot(driver, "page-sam.png")
        send.click()
        seen.add(key)
        answered += 1
        if answered == stop_after:
            return answered
    raise SystemExit(f"the session did not finish in time ({answered} answers)")


def trials(log):
    rows = [json.loads(l) for l in log.read_text().splitlines()]
    return [r for r in rows if r["kind"] == "trial"]


def main():
    sleeve = subprocess.Popen([pty_sleeve, "10"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    port = sleeve.stdout.readline().strip()
    plan = work / "emoji.toml"
    plan.write_text((ROOT / "examples/study/emoji.toml").read_text().replace("retry_pause_s = 5.0", "retry_pause_s = 0.5"))
    log = work / "b1.jsonl"
    opts = webdriver.ChromeOptions()
    opts.binary_location = "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1000,1300"):
        opts.add_argument(a)
    driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=opts)
    try:
        run, url = start(plan, port, log, False)
        driver.get(url)
        participant(driver, stop_after=8)
        time.sleep(0.2)
        run.kill()
        run.wait()
        before = trials(log)
        assert len(before) in (7, 8), f"{len(before)} trials logged before the kill"
        time.sleep(1.0)
        assert "Waiting for the experimenter" in text(driver), text(driver)
        run, url = start(plan, port, log, True)
        driver.get(url)
        participant(driver)
        assert run.wait(timeout=30) == 0
    finally:
        driver.quit()
        sleeve.stdin.close()
    rows = trials(log)
    assert len(rows) == 3 * 6 + 6, len(rows)
    keys = {(r["round"], r["position"]) for r in rows}
    assert len(keys) == len(rows), "a trial was repeated"
    for rnd in range(1, 5):
        names = sorted(r["stimulus"] for r in rows if r["round"] == rnd)
        assert len(names) == 6 and len(set(names)) == 6, (rnd, names)
    for r in rows:
        assert r["end_tick"] is not None and r["end_tick"] > r["start_tick"] + 100, r
        assert (r["p"] is None) == (r["round"] == 4), r
    out = work / "report"
    subprocess.run([touchc, "study", "report", str(log), "-o", str(out)], check=True)
    report = json.loads((out / "report.json").read_text())
    assert report["trials"] == 18 and report["valence"]["count"] == [1] * 6, report["trials"]
    print(f"ok: {len(rows)} trials in headless Chromium, killed after {len(before)} and resumed; report checked")


main()
