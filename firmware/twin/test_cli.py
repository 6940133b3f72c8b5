"""The real `touchc sleeve` against the twin served on a pseudo-terminal, as a user
runs it: every subcommand, two programs on one port, a stream from a host that
stalls, an upload that is killed.

Run by `firmware/twin/run.sh` (with `test_twin`). The twin runs in step with the wall
clock in a thread of this process; each `touchc` is a process of its own.
"""

import gc
import json
import os
import random
import signal
import subprocess
import threading
import time
import unittest
from pathlib import Path

import twin
from test_twin import EMOJI, IDLE, ROOT, SCRATCH, TOUCHC, boot, codes, expected, find, has_link

EMOJI_DIR = ROOT / "examples/emoji"
# The emoji stimuli's ramp, ms (`touchc inspect`).
RAMP_MS = {"love": 10, "gratitude": 10}


def render_codes(stimulus):
    """`touchc render --csv` of a stimulus as output codes per tick (the sleeve's
    1 A full scale: a code is 1/2048 A)."""
    out = subprocess.run([str(TOUCHC), "render", "--csv", str(stimulus)], check=True,
                         capture_output=True, text=True).stdout
    rows = out.splitlines()[1:]
    return [tuple(round(float(a) * 2048) + 2048 for a in r.split(",")[1:]) for r in rows]


class Served(unittest.TestCase):
    """A twin served on a pseudo-terminal for each test, and `touchc sleeve` on it."""

    def serve(self, board):
        if not has_link():
            self.skipTest("this ELF has no USART link (no USART2 handler)")
        if not TOUCHC.exists():
            self.skipTest(f"{TOUCHC} not built (run.sh builds it)")
        SCRATCH.mkdir(parents=True, exist_ok=True)
        self.board, self.port = board, SCRATCH / "cli-pty"
        # The boards of the tests before (the whole suite runs in one process) are
        # collected now, not in a pause of the serve thread while the CLI waits on its
        # reply timeout: the twin keeps pace with the wall clock only while it runs.
        gc.collect()
        stop = threading.Event()
        server = threading.Thread(target=twin.serve, args=(board, str(self.port)), kwargs={"stop": stop})
        server.start()
        self.addCleanup(server.join)
        self.addCleanup(stop.set)
        deadline = time.monotonic() + 10
        while not self.port.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        # The boot's bank check, then the link answers.
        self.wait_until(lambda: self.board.now() > 0.3)

    def wait_until(self, cond, timeout=30):
        deadline = time.monotonic() + timeout
        while not cond():
            self.assertLess(time.monotonic(), deadline, "timed out")
            time.sleep(0.01)

    def args(self, *args):
        return [str(TOUCHC), "sleeve", "--port", str(self.port), *args]

    def touchc(self, *args, timeout=60):
        return subprocess.run(self.args(*args), capture_output=True, text=True, timeout=timeout)

    def ok(self, *args):
        r = self.touchc(*args)
        self.assertEqual(r.returncode, 0, f"touchc sleeve {' '.join(args)}: {r.stderr}")
        return r

    def fails(self, *args, says):
        """A failure in one line that says `says`, exit 1."""
        r = self.touchc(*args)
        self.assertEqual(r.returncode, 1, f"touchc sleeve {' '.join(args)}: {r.stdout} {r.stderr}")
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn(says, r.stderr)
        return r

    def holding(self, proc):
        """True once `proc` has the port open."""
        target = os.path.realpath(self.port)
        try:
            fds = os.listdir(f"/proc/{proc.pid}/fd")
        except FileNotFoundError:
            return False
        for fd in fds:
            try:
                if os.readlink(f"/proc/{proc.pid}/fd/{fd}") == target:
                    return True
            except OSError:
                pass
        return False


class Commands(Served):
    """info, status, play, stop, events; a second program on the port."""

    def test_every_command_on_the_built_bank(self):
        b = boot(EMOJI)
        self.serve(b)
        info = self.ok("info")
        self.assertIn("slot  0: attention", info.stdout)
        got = json.loads(self.ok("info", "--json").stdout)
        self.assertEqual(got["bank"]["state"], "flashed")
        self.assertEqual(len(got["slots"]), 6)
        status = json.loads(self.ok("status", "--json").stdout)
        self.assertIsNone(status["playing"])

        # Play slot 2 by command: the host player's codes, until the stop.
        since = len(b.frames)
        play = json.loads(self.ok("play", "2", "--json").stdout)
        self.wait_until(lambda: b.now() > play["tick"] / 1000 + 0.2)
        status = json.loads(self.ok("status", "--json").stdout)
        self.assertEqual(status["playing"], {"source": "slot", "slot": 2})
        stop = json.loads(self.ok("stop", "--json").stdout)
        self.assertEqual((stop["stopped"], stop["source"], stop["slot"]), (True, "slot", 2))
        want = expected(EMOJI, 2)[0]
        frames = codes(b)
        n = (stop["tick"] - play["tick"]) - 5
        self.assertGreater(n, 100)
        self.assertIsNotNone(find(frames, want[:n], since, len(frames)), "slot 2 as the host plays it")
        self.wait_until(lambda: b.frames[-1][1] == IDLE)

        # `events` holds the port; a second program is told so in one line, and the
        # first is not disturbed: it prints the button's events.
        events = subprocess.Popen(self.args("events", "--count", "2", "--duration", "60"),
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            self.wait_until(lambda: self.holding(events))
            time.sleep(0.3)  # its hello answered
            r = self.fails("status", says="in use by ")
            self.assertIn(f"touchc (pid {events.pid})", r.stderr)
            self.assertNotIn("no sleeve", r.stderr)
            at = b.now() + 0.2
            b.press(at, 0.08)
            out, err = events.communicate(timeout=60)
        finally:
            events.kill()
            events.wait()
        self.assertEqual(events.returncode, 0, err)
        lines = [json.loads(line) for line in out.splitlines()]
        self.assertEqual([e["event"] for e in lines][:2], ["button", "started"], lines)
        self.assertEqual(lines[1]["slot"], 2, "a press plays the slot selected last")
        # The port is free again: the second program works now.
        self.ok("stop")

    def test_a_missing_port_still_says_no_sleeve(self):
        if not TOUCHC.exists():
            self.skipTest(f"{TOUCHC} not built (run.sh builds it)")
        self.port = SCRATCH / "no-such-port"
        self.fails("info", says="no sleeve attached there (no such port)")


class FoundByItself(Served):
    """A twin served at its default link (in the temporary directory) is the port
    when it is the only sleeve; no port at all is an empty list, not an error."""

    def test_list_shows_the_twin_and_info_needs_no_port(self):
        if not TOUCHC.exists():
            self.skipTest(f"{TOUCHC} not built (run.sh builds it)")
        tmp = SCRATCH / "tmp-empty"
        tmp.mkdir(parents=True, exist_ok=True)
        env = dict(os.environ, TMPDIR=str(tmp))
        r = subprocess.run([str(TOUCHC), "sleeve", "list"], capture_output=True, text=True, env=env, timeout=60)
        if r.stdout.strip():
            self.skipTest(f"this machine has serial ports: {r.stdout}")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("firmware/twin/run.sh serve", r.stderr)
        tmp = SCRATCH / "tmp-twin"
        tmp.mkdir(parents=True, exist_ok=True)
        b = boot(EMOJI)
        board_port = tmp / "touchc-sleeve-twin"
        stop = threading.Event()
        server = threading.Thread(target=twin.serve, args=(b, str(board_port)), kwargs={"stop": stop})
        server.start()
        self.addCleanup(server.join)
        self.addCleanup(stop.set)
        self.wait_until(lambda: board_port.exists() and b.now() > 0.3)
        env = dict(os.environ, TMPDIR=str(tmp))
        r = subprocess.run([str(TOUCHC), "sleeve", "list"], capture_output=True, text=True, env=env, timeout=60)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("sleeve twin", r.stdout)
        r = subprocess.run([str(TOUCHC), "sleeve", "info"], capture_output=True, text=True, env=env, timeout=60)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("slot  0: attention", r.stdout)


class KilledUpload(Served):
    """`touchc sleeve upload` killed once the erase began: the sleeve says what
    works, `touchc sleeve abort` ends the upload, and the sleeve ends one by itself
    10 s after its last chunk; the built-in bank plays after either."""

    def kill_an_upload(self, b):
        """Starts an upload and kills it once the erase is done; returns the time."""
        up = subprocess.Popen(self.args("upload", str(EMOJI)), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            self.wait_until(lambda: (b.erases and b.t > b.erases[-1][1]) or up.poll() is not None)
            self.assertIsNone(up.poll(), "the upload ended before it could be killed")
            up.kill()
        finally:
            up.kill()
            up.communicate()
        return b.now()

    def assert_builtin_plays(self):
        got = json.loads(self.ok("info", "--json").stdout)
        self.assertEqual(got["bank"]["state"], "builtin", got["bank"])
        play = json.loads(self.ok("play", "0", "--json").stdout)
        self.assertTrue(play["now"])
        self.ok("stop")

    def test_abort_ends_a_killed_upload(self):
        b = boot(EMOJI)
        self.serve(b)
        self.kill_an_upload(b)
        for args in (("play", "0"), ("info",)):
            r = self.fails(*args, says="an upload is in progress, or was left unfinished")
            self.assertIn("`touchc sleeve abort` ends it", r.stderr)
        r = self.ok("abort")
        self.assertIn("restarted into its built-in bank", r.stderr)
        self.assert_builtin_plays()
        r = self.ok("abort")
        self.assertIn("no upload in progress", r.stderr)

    def test_a_killed_upload_ends_by_itself(self):
        b = boot(EMOJI)
        self.serve(b)
        killed = self.kill_an_upload(b)
        resets = len(b.resets)
        # Another program asking meanwhile does not keep the upload alive.
        while b.now() < killed + 9:
            self.fails("play", "0", says="left unfinished")
            time.sleep(1)
        self.wait_until(lambda: len(b.resets) > resets, timeout=60)
        # 10 s after the last chunk arrived; the link's task looks once a second.
        self.assertLessEqual(b.resets[-1][0] / twin.T_HZ - killed, 11.2)
        self.assert_builtin_plays()


class Stream(Served):
    """`touchc sleeve stream` from a host that stalls at random points."""

    def test_a_stalling_host_streams_whole_stimuli(self):
        b = boot(EMOJI)
        self.serve(b)
        rng = random.Random(33)
        worst = 0.0
        # Two streams, the second straight after the first: nothing of the first
        # (its player, its state) may carry into the second.
        for name in ("love", "gratitude"):
            stimulus = EMOJI_DIR / f"{name}.touch"
            # The signal tick for tick; the stream's final ramp starts where its last
            # keyframe is played out and may differ from the render's by a code.
            render = render_codes(stimulus)
            want = render[:len(render) - RAMP_MS[name] - 1]
            since = len(b.frames)
            proc = subprocess.Popen(self.args("stream", str(stimulus)), stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, text=True)
            # The host stopped for up to 100 ms at random points (SIGSTOP, SIGCONT).
            try:
                while proc.poll() is None:
                    time.sleep(rng.uniform(0.05, 0.4))
                    stall = rng.uniform(0.0, 0.1)
                    try:
                        os.kill(proc.pid, signal.SIGSTOP)
                        time.sleep(stall)
                    finally:
                        os.kill(proc.pid, signal.SIGCONT)
                    worst = max(worst, stall)
                out, err = proc.communicate(timeout=120)
            finally:
                proc.kill()
                proc.wait()
            self.assertEqual(proc.returncode, 0, f"{name}: {err}")
            self.assertIn("streamed", err)
            frames = codes(b)
            at = find(frames, want, since, len(frames) - len(want) + 1)
            if at is None:
                # Where the stream parts from the render, for the message.
                first = next(i for i in range(since, len(frames)) if frames[i] != IDLE)
                lead = next((k for k, w in enumerate(want) if w != IDLE), 0)
                o = first - lead
                bad = next((k for k in range(len(want)) if o + k >= len(frames) or frames[o + k] != want[k]), None)
                self.fail(f"{name}: not `touchc render`'s codes tick for tick: tick {bad} of {len(want)}: "
                          f"{frames[o + bad] if bad is not None and o + bad < len(frames) else None} "
                          f"vs {want[bad] if bad is not None else None}")
        if os.environ.get("TWIN_VERBOSE"):
            print(f"\nstreams whole with host stalls of up to {worst * 1000:.0f} ms")



class CutUpload(Served):
    """`touchc sleeve upload` with the power cut at three points: the message says
    what happened, at once (no 10 s timeout), and the sleeve plays."""

    def cut_at(self, b, kind, when):
        """Cuts the power once, at the first flash operation of `kind` for which
        `when(arg)` holds, as it starts."""
        state = {"done": False}

        def look(k, arg):
            if k == kind and not state["done"] and when(arg):
                state["done"] = True
                b.power_cut()
        b.on_flash = look
        return state

    def upload(self, b):
        start = time.monotonic()
        r = self.touchc("upload", str(EMOJI))
        return r, time.monotonic() - start

    def test_a_cut_after_the_head_finds_the_new_bank_in_place(self):
        b = boot(EMOJI, erase=True)
        self.serve(b)
        cut = self.cut_at(b, "program", lambda addr: addr == twin.BANK_BASE)
        r, took = self.upload(b)
        self.assertTrue(cut["done"], f"the commit never programmed the head: {r.stderr}")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("restarted before it answered the upload's commit", r.stderr)
        self.assertIn("with the new bank in place: verified", r.stderr)
        self.assertLess(took, 8, "waited out a timeout")
        got = json.loads(self.ok("info", "--json").stdout)
        self.assertEqual(got["bank"]["state"], "flashed", got["bank"])

    def test_a_cut_during_the_erase_is_told_at_once(self):
        b = boot(EMOJI)
        self.serve(b)
        # Half a second into the first sector's erase (about a second long).
        cut = {"done": False}

        def look(kind, _):
            if kind == "erase" and not cut["done"]:
                cut["done"] = True
                b.at(b.now() + 0.5, lambda b: b.reset("power"))
        b.on_flash = look
        r, took = self.upload(b)
        self.assertTrue(cut["done"], r.stderr)
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("the sleeve restarted during the upload", r.stderr)
        self.assertIn("the upload was lost: run it again", r.stderr)
        self.assertLess(took, 5, "waited out the erase's 10 s timeout")
        self.ok("play", "0")
        self.ok("stop")

    def test_a_cut_mid_chunks_says_the_upload_was_lost(self):
        b = boot(EMOJI)
        self.serve(b)
        cut = self.cut_at(b, "program", lambda addr: addr >= twin.BANK_BASE + 2048)
        r, _ = self.upload(b)
        self.assertTrue(cut["done"], r.stderr)
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("the sleeve restarted during the upload", r.stderr)
        self.assertIn("the upload was lost: run it again", r.stderr)
        self.assertNotIn("no upload in progress", r.stderr)
        got = json.loads(self.ok("info", "--json").stdout)
        self.assertEqual(got["bank"]["state"], "builtin", got["bank"])


if __name__ == "__main__":
    unittest.main()
