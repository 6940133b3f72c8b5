"""The firmware README's study script with its own waits, against the twin served on a
pseudo-terminal (in step with the wall clock): each trial's logged tick is its onset.

Run by `firmware/twin/run.sh` beside `test_twin`. The script's defaults once logged
the ramp down of the previous stimulus for five trials in six (a 4 s gap against
emoji of 6.2-8.5 s); it now waits for each stimulus to end, and says so on stderr when
a trial could not start at once.
"""

import json
import os
import subprocess
import threading
import time
import unittest

import twin
from test_twin import EMOJI, SCRATCH, TOUCHC, boot, has_link, study_script


class StudyOnsets(unittest.TestCase):
    def serving(self, board):
        """Serves `board` on a pseudo-terminal in a thread; returns its path."""
        if not has_link():
            self.skipTest("this ELF has no USART link (no USART2 handler)")
        if not TOUCHC.exists():
            self.skipTest(f"{TOUCHC} not built (run.sh builds it)")
        SCRATCH.mkdir(parents=True, exist_ok=True)
        port = SCRATCH / "study-pty"
        stop = threading.Event()
        server = threading.Thread(target=twin.serve, args=(board, str(port)), kwargs={"stop": stop})
        server.start()
        self.addCleanup(server.join)
        self.addCleanup(stop.set)
        deadline = time.monotonic() + 10
        while not port.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        return port

    def test_every_trial_logs_its_own_onset_and_a_late_one_is_said(self):
        board = boot(EMOJI)
        port = self.serving(board)
        script, log = SCRATCH / "study-onsets.sh", SCRATCH / "study-onsets.jsonl"
        script.write_text(study_script())
        log.unlink(missing_ok=True)
        env = dict(os.environ, PATH=f"{TOUCHC.parent}:{os.environ['PATH']}", REPS="1", GAP="0")
        run = lambda *a: subprocess.run([str(TOUCHC), "sleeve", "--port", str(port), *a],
                                        capture_output=True, text=True, check=True, timeout=60)
        lengths = [s["duration_ms"] for s in json.loads(run("info", "--json").stdout)["slots"]]
        # Something still playing when the study starts (a button pressed): the first
        # trial has to wait for it, and the script says so.
        run("play", "0")
        study = subprocess.run(["bash", str(script), str(port), str(log)], env=env,
                               capture_output=True, text=True, timeout=300)
        self.assertEqual(study.returncode, 0, study.stderr)
        trials = [json.loads(line) for line in log.read_text().splitlines()]
        self.assertEqual(sorted(t["slot"] for t in trials), list(range(len(lengths))), trials)
        late = [t for t in trials if not t["now"]]
        self.assertEqual(late, trials[:1], "only the trial that met the pressed stimulus")
        self.assertEqual(study.stderr.count("did not start at once"), 1, study.stderr)
        for before, after in zip(trials, trials[1:]):
            self.assertGreaterEqual(after["tick"] - before["tick"], lengths[before["slot"]],
                                    f"slot {after['slot']} began before slot {before['slot']} ended")
        self.assertEqual(board.resets, [])


if __name__ == "__main__":
    unittest.main()
