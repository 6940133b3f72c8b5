"""The link under a host that sends faster than it reads: every request answered
once, on the release ELF (`bash firmware/twin/run.sh test_link`)."""

import collections
import os
import unittest

import link
import twin
from test_twin import EMOJI, Host, boot, has_link


class PipelinedFlood(unittest.TestCase):
    """Status requests written back to back over USART2 while a slot plays, far
    faster than their replies can leave (a request is 7 bytes on the wire, a
    `Status` reply about 40): each gets exactly one answer, its reply, `QueueFull`
    for a full queue of commands for the tick, or `Unreadable` for a frame the
    device had no room for (no `seq`: counted against the requests)."""

    REQUESTS = 600

    @classmethod
    def setUpClass(cls):
        if not has_link():
            raise unittest.SkipTest("this ELF has no USART link (no USART2 handler)")
        b = cls.board = boot(EMOJI)
        h = cls.host = Host(b)
        b.run(0.3)
        h.ok(link.play, 0)
        first = h.seq + 1
        cls.seqs = list(range(first, first + cls.REQUESTS))
        h.seq = cls.seqs[-1]
        cls.sent = b.t
        cls.wire_end = h.u.send(b"".join(link.status(s) for s in cls.seqs))
        since = len(h.messages)
        # The flood is about 100 ms on the wire; its answers, at most 40 bytes
        # each, leave within a second.
        h.pump(1.2)
        cls.messages = [m for _, m in h.messages[since:]]

    def answers(self):
        by_seq = collections.defaultdict(list)
        for m in self.messages:
            if m["kind"] in ("reply", "refused"):
                by_seq[m["seq"]].append(m)
        return by_seq

    def test_every_request_gets_exactly_one_answer(self):
        by_seq = self.answers()
        unreadable = [m for m in self.messages if m["kind"] == "unreadable"]
        twice = {s: a for s, a in by_seq.items() if len(a) > 1}
        self.assertEqual(twice, {}, "requests answered more than once")
        self.assertLessEqual(set(by_seq), set(self.seqs), "answers to requests never sent")
        replies = sum(1 for a in by_seq.values() if a[0]["kind"] == "reply")
        full = sum(1 for a in by_seq.values() if a[0]["kind"] == "refused")
        if os.environ.get("TWIN_VERBOSE"):
            reasons = collections.Counter(m["error"] for m in unreadable)
            print(f"\n{self.REQUESTS} status requests back to back: {replies} replies, {full} QueueFull, "
                  f"{len(unreadable)} unreadable {dict(reasons)}, "
                  f"{self.REQUESTS - len(by_seq) - len(unreadable)} unanswered; wire "
                  f"{(self.wire_end - self.sent) / twin.T_HZ * 1000:.0f} ms")
        self.assertEqual(len(by_seq) + len(unreadable), self.REQUESTS, "a request without an answer")
        self.assertGreater(replies, 0)

    def test_a_full_queue_is_refused_as_such(self):
        errors = collections.Counter(a[0]["error"] for a in self.answers().values()
                                     if a[0]["kind"] == "refused")
        self.assertEqual(set(errors), {"QueueFull"}, errors)
        unreadable = {m["error"] for m in self.messages if m["kind"] == "unreadable"}
        self.assertLessEqual(unreadable, {"Overrun", "Cobs", "BadCrc", "Short"})

    def test_nothing_is_lost_to_the_usarts_own_overrun(self):
        self.assertEqual(self.board.usart2.overruns, 0)


if __name__ == "__main__":
    unittest.main()
