"""The sleeve's USB socket on the twin: the OTG FS model's own checks, then the
release ELF built with USB (`TWIN_ELF`) enumerated by the scripted host and the link
carried over its bulk endpoints.

Run by `firmware/twin/run.sh test_usb` (ci.sh runs it on the usb build).
"""

import os
import struct
import subprocess
import threading
import time
import unittest
import zlib

import link
import otg_fs
import twin
import usb_host
import test_twin
from test_twin import CODES, ELF, EMOJI, IDLE, MS, SCRATCH, Host, bare_board, upload

O = otg_fs
UID = bytes(range(0x30, 0x3C))  # a 96-bit unique ID (RM0090 39.1) for the board under test


def has_usb():
    """The ELF handles OTG_FS's interrupt, not the default handler."""
    segments, symbols = twin.load_elf(ELF)
    for addr, data in segments:
        if addr == twin.FLASH_BASE:
            at = 4 * (16 + O.IRQ)
            vector = int.from_bytes(data[at:at + 4], "little") & ~1
            return vector != symbols.get("DefaultHandler", -1) & ~1
    return False


def usb_board(uid=UID, plug_at=0.05, bank=None, erase=False):
    """The ELF on a board with its OTG FS, a host on its port, the cable plugged."""
    b = twin.Board(ELF)
    if bank is not None:
        b.set_bank(bank)
    elif erase:
        b.set_bank(b"")
    otg_fs.write_uid(b, uid)
    otg = b.attach(otg_fs.OtgFs(b))
    h = usb_host.UsbHost(b, otg)
    b.at(plug_at, lambda _: h.plug(True))
    return b, otg, h


class UsbLink(Host):
    """test_twin's link host, over the CDC-ACM port instead of USART2. A request
    waits for the port (after a restart the sleeve enumerates again); its end is the
    time the device took its last packet."""

    def __init__(self, board, usb):
        super().__init__(board)
        self.u = usb

    def call(self, make, *args, timeout=1.0):
        if self.u.state != "configured":
            self.u.port_ready(timeout=2.0)
        self.seq += 1
        self.u.send(make(self.seq, *args))
        deadline = self.b.t + round(timeout * twin.T_HZ)
        end = None
        while self.b.t < deadline:
            self.b.run(usb_host.STEP_S)
            if end is None and not self.u.tx:
                end = self.u.sent_at
            for _, m in self.collect():
                if m["kind"] in ("reply", "refused") and m["seq"] == self.seq:
                    return m, end
        raise AssertionError(f"no answer to {make.__name__}{args} over USB in {timeout} s")


# ----------------------------------------------------------------- the model


class OtgModel(unittest.TestCase):
    """The model against RM0090's programming model, register by register."""

    def setUp(self):
        b = self.b = bare_board()
        b.poke(0x4002_3834, 1 << 7)  # RCC_AHB2ENR.OTGFSEN
        self.o = b.attach(O.OtgFs(b))

    def w(self, off, v):
        self.o.write(off, v)

    def r(self, off):
        return self.o.read(off)

    def m(self, off, bits):
        """Read-modify-write, as the driver changes a register."""
        self.o.write(off, self.o.read(off) | bits)

    def connect(self):
        """PHY on with VBUS sensing, cable in, session valid, pull-up on."""
        self.w(O.GCCFG, 1 << 16 | 1 << 19)
        self.w(O.GAHBCFG, 1)
        self.o.set_vbus(True)
        self.b.run(2 * O.SESSION_S)
        self.assertTrue(self.o.connected())

    def test_vbus_sensing_raises_srqint_then_sedet(self):
        self.w(O.GCCFG, 1 << 16 | 1 << 19)
        self.w(O.GINTMSK, O.SRQINT | O.OTGINT)
        self.w(O.GAHBCFG, 1)
        self.assertFalse(self.o.connected())
        self.o.set_vbus(True)
        self.assertEqual(self.b.gpio[0].level(9), 1, "VBUS is on PA9")
        self.b.run(2 * O.SESSION_S)
        self.assertTrue(self.r(O.GINTSTS) & O.SRQINT)
        self.assertTrue(self.r(O.GOTGCTL) & 1 << 19, "B-session valid")
        self.assertTrue(self.o.irq_line())
        self.w(O.GINTSTS, O.SRQINT)
        self.assertFalse(self.o.irq_line(), "SRQINT is rc_w1")
        self.w(O.DCTL, 2)
        self.assertFalse(self.o.connected(), "SDIS holds D+ low")
        self.w(O.DCTL, 0)
        self.assertTrue(self.o.connected())
        self.o.set_vbus(False)
        self.b.run(2 * O.SESSION_S)
        self.assertTrue(self.r(O.GOTGINT) & 1 << 2, "SEDET")
        self.assertTrue(self.r(O.GINTSTS) & O.OTGINT)
        self.w(O.GOTGINT, 1 << 2)
        self.assertFalse(self.r(O.GINTSTS) & O.OTGINT)
        self.assertFalse(self.o.connected())

    def test_setup_goes_through_the_rx_fifo_with_its_status_entries(self):
        self.connect()
        self.w(O.GRXFSIZ, 64)
        self.w(O.DOEPMSK, O.STUP)
        self.w(O.DAINTMSK, 1 << 16)
        self.w(O.GINTMSK, O.RXFLVL | O.OEPINT)
        self.o.bus_reset()
        self.assertTrue(self.r(O.GINTSTS) & O.USBRST)
        self.assertIsNone(self.o.setup(0, bytes(8)), "no answer during the reset")
        self.o.reset_done()
        self.assertTrue(self.r(O.GINTSTS) & O.ENUMDNE)
        self.assertIsNone(self.o.setup(3, bytes(8)), "not its address")
        self.assertEqual(self.o.setup(0, bytes([0x80, 6, 0, 1, 0, 0, 18, 0])), "ACK")
        self.assertTrue(self.r(O.GINTSTS) & O.RXFLVL)
        st = self.r(O.GRXSTSP)
        self.assertEqual((st & 0xF, st >> 4 & 0x7FF, st >> 17 & 0xF), (0, 8, O.SETUP_DATA))
        self.assertEqual(self.r(0x1000), 0x0100_0680)
        self.assertEqual(self.r(0x1000), 0x0012_0000)
        self.assertFalse(self.r(0xB08) & O.STUP, "STUP waits for the SETUP-done entry")
        st = self.r(O.GRXSTSP)
        self.assertEqual(st >> 17 & 0xF, O.SETUP_DONE)
        self.assertFalse(self.r(O.GINTSTS) & O.RXFLVL)
        self.assertTrue(self.r(0xB08) & O.STUP)
        self.assertEqual(self.r(O.DAINT), 1 << 16)
        self.assertTrue(self.r(O.GINTSTS) & O.OEPINT)
        self.w(0xB08, O.STUP)
        self.assertFalse(self.r(O.GINTSTS) & O.OEPINT)

    def test_in_packets_come_from_the_tx_fifo_with_their_toggle(self):
        self.connect()
        self.w(O.DIEPTXF0, 16 << 16 | 32)
        self.w(O.DIEPMSK, O.XFRC)
        self.w(O.DAINTMSK, 1)
        self.o.setup(0, bytes(8))
        self.assertEqual(self.o.in_(0, 0), "NAK", "nothing armed")
        self.assertEqual(self.r(0x918), 16, "DTXFSTS: the whole FIFO free")
        self.w(0x910, 1 << 19 | 6)  # one packet, 6 bytes
        self.m(0x900, O.EPENA | O.CNAK)
        self.w(0x1000, 0x6463_6261)
        self.assertEqual(self.o.in_(0, 0), "NAK", "the packet is not all in the FIFO")
        self.w(0x1000, 0x0000_6665)
        self.assertEqual(self.r(0x918), 14)
        self.assertEqual(self.o.in_(0, 0), ("DATA", 1, b"abcdef"), "DATA1 after a SETUP")
        self.assertTrue(self.r(0x908) & O.XFRC)
        self.assertFalse(self.r(0x900) & O.EPENA, "the transfer is done")
        self.assertTrue(self.r(O.GINTSTS) & O.IEPINT)
        self.assertEqual(self.o.in_(0, 0), "NAK")

    def test_bulk_out_toggles_nak_and_drop_a_repeated_pid(self):
        self.connect()
        self.w(O.GRXFSIZ, 64)
        self.w(0xB20, O.USBAEP | 2 << 18 | 64 | O.SD0PID)  # EP1 OUT, bulk, 64 bytes
        self.w(0xB30, 1 << 19 | 64)
        self.assertEqual(self.o.out(0, 1, b"x", 0), "NAK", "NAK until cleared")
        self.m(0xB20, O.CNAK | O.EPENA)
        self.assertEqual(self.o.out(0, 1, b"hi", 0), "ACK")
        self.assertEqual(self.r(0xB20) >> 16 & 1, 1, "DPID now DATA1")
        self.assertEqual(self.o.out(0, 1, b"hi", 0), "NAK", "a short packet ends the transfer")
        st = self.r(O.GRXSTSP)
        self.assertEqual((st & 0xF, st >> 4 & 0x7FF, st >> 17 & 0xF), (1, 2, O.OUT_DATA))
        self.assertEqual(self.r(0x1000) & 0xFFFF, 0x6968)
        self.assertEqual(self.r(O.GRXSTSP) >> 17 & 0xF, O.OUT_DONE)
        self.assertTrue(self.r(0xB28) & O.XFRC)
        self.w(0xB30, 1 << 19 | 64)
        self.m(0xB20, O.CNAK)
        self.assertEqual(self.o.out(0, 1, b"again", 0), "ACK", "DATA0 again: a retransmission")
        self.assertFalse(self.r(O.GINTSTS) & O.RXFLVL, "acknowledged and dropped")
        self.m(0xB20, O.SD0PID)
        self.assertEqual(self.o.out(0, 1, b"new", 0), "ACK")
        self.assertTrue(self.r(O.GINTSTS) & O.RXFLVL, "after SD0PID, DATA0 is new data")

    def test_the_interrupt_line_needs_gint_and_the_mask(self):
        self.w(O.GCCFG, 1 << 16 | 1 << 19)
        self.o.set_vbus(True)
        self.b.run(2 * O.SESSION_S)
        self.assertFalse(self.o.irq_line(), "GAHBCFG.GINT clear")
        self.w(O.GAHBCFG, 1)
        self.assertFalse(self.o.irq_line(), "SRQINT masked")
        self.w(O.GINTMSK, O.SRQINT)
        self.assertTrue(self.o.irq_line())

    def test_a_new_address_answers_after_the_status_stage(self):
        self.connect()
        self.w(O.DIEPTXF0, 16 << 16 | 32)
        self.o.setup(0, bytes([0, 5, 7, 0, 0, 0, 0, 0]))
        self.w(O.DCFG, 7 << 4)
        self.w(0x910, 1 << 19)
        self.m(0x900, O.EPENA | O.CNAK)
        self.assertEqual(self.o.in_(7, 0), None, "the status stage is still at address 0")
        self.assertEqual(self.o.in_(0, 0), ("DATA", 1, b""))
        self.assertEqual(self.o.setup(7, bytes(8)), "ACK")


# ------------------------------------------------------------ the usb build


def needs_usb(cls):
    return unittest.skipUnless(has_usb(), "this ELF has no USB (no OTG_FS handler)")(cls)


@needs_usb
class Enumeration(unittest.TestCase):
    """Plugged in, the sleeve enumerates as a CDC-ACM port that says what it is."""

    @classmethod
    def setUpClass(cls):
        cls.b, cls.otg, cls.h = usb_board()
        cls.h.port_ready(timeout=1.0)
        cls.link = UsbLink(cls.b, cls.h)

    def test_the_device_descriptor(self):
        d = self.h.descriptors["device"]
        self.assertEqual(len(d), 18)
        bcd, cls_, sub, proto, mps0, vid, pid = struct.unpack_from("<HBBBBHH", d, 2)
        self.assertEqual((cls_, sub, proto), (0xEF, 2, 1), "IAD: miscellaneous class")
        self.assertEqual(mps0, 64)
        self.assertEqual((vid, pid), (0x1209, 0x0001))
        self.assertEqual(d[17], 1, "one configuration")

    def test_the_configuration_is_cdc_acm_with_its_endpoints(self):
        cfg = self.h.descriptors["configuration"]
        self.assertEqual(struct.unpack_from("<H", cfg, 2)[0], len(cfg))
        ifaces = [cfg[i:i + 9] for i in range(len(cfg)) if cfg[i:i + 2] == b"\x09\x04"]
        self.assertEqual([(x[5], x[6]) for x in ifaces], [(2, 2), (10, 0)], "CDC ACM control, CDC data")
        eps = sorted(self.h.endpoints())
        self.assertEqual(eps, [(0x01, 2, 64), (0x81, 3, 8), (0x82, 2, 64)])

    def test_self_powered_drawing_nothing_from_vbus(self):
        cfg = self.h.descriptors["configuration"]
        self.assertEqual(cfg[7] & 0xC0, 0xC0, "bmAttributes: self-powered")
        self.assertLessEqual(cfg[8], 50, "bMaxPower: 100 mA or less (the sleeve has its own supply)")

    def test_the_strings_say_what_it_is_and_which_one(self):
        d = self.h.descriptors["device"]
        self.assertEqual(self.h.strings[d[14]], "touchc")
        self.assertEqual(self.h.strings[d[15]], "touchc sleeve")
        self.assertTrue(d[16], "a serial number string")
        self.assertEqual(self.h.strings[d[16]], UID.hex().upper())

    def test_the_serial_number_is_the_boards_own(self):
        b, _, h = usb_board(uid=bytes(range(0xA0, 0xAC)))
        h.port_ready(timeout=1.0)
        d = h.descriptors["device"]
        self.assertEqual(h.strings[d[16]], bytes(range(0xA0, 0xAC)).hex().upper())

    def test_configured_within_half_a_second_of_vbus(self):
        t = (self.h.configured_at - round(0.05 * twin.T_HZ)) / MS
        if os.environ.get("TWIN_VERBOSE"):
            print(f"\nenumeration: configured {t:.1f} ms after VBUS")
        self.assertLess(t, 500)
        self.assertEqual(self.otg.errors, [])

    def test_requests_over_bulk(self):
        m, _ = self.link.ok(link.hello)
        self.assertEqual(m["version"], 1)
        self.link.ok(link.request, "Info")
        self.link.ok(link.status)

    def test_a_reply_of_several_packets_ends_short_or_with_a_zlp(self):
        h = self.h
        before = len(h.in_packets)
        m, _ = self.link.ok(link.request, "BankRead", link.varint(0), link.varint(link.MAX_CHUNK))
        sizes = [n for _, n in h.in_packets[before:]]
        self.assertGreaterEqual(len(sizes), 5, "256 bytes of bank and the frame: 5 packets or more")
        self.assertTrue(all(n == 64 for n in sizes[:-1]))
        self.assertLess(sizes[-1], 64, "the last packet is short (or a zero-length one)")
        # Requests packed back to back into 64-byte OUT packets, and split across them.
        before = len(self.link.messages)
        burst = b"".join(link.hello(900 + i) for i in range(20))
        h.send(burst)
        self.link.pump(0.05)
        replies = [m for _, m in self.link.messages[before:] if m["kind"] == "reply"]
        self.assertEqual([m["seq"] for m in replies], list(range(900, 920)))
        self.assertEqual(h.dropped, [])


    def test_a_reply_of_whole_packets_ends_with_a_zero_length_one(self):
        h, whole = self.h, 0
        for n in range(1, 120):
            before = len(h.in_packets)
            self.link.ok(link.request, "BankRead", link.varint(0), link.varint(n))
            self.link.pump(0.002)
            sizes = [k for _, k in h.in_packets[before:]]
            if sum(sizes) % 64 == 0:
                whole += 1
                self.assertEqual(sizes[-1], 0, f"BankRead of {n}: {sizes}")
            else:
                self.assertNotIn(0, sizes, f"BankRead of {n}: {sizes}")
        self.assertGreater(whole, 0, "some reply filled its last packet")


@needs_usb
class DataToggles(unittest.TestCase):
    """USB 2.0 9.4.5 and 9.1.1.5: after SET_CONFIGURATION and after
    CLEAR_FEATURE(ENDPOINT_HALT), an endpoint's next packet is DATA0. A host that
    sends them must lose no request."""

    def scenario(self, request):
        b, otg, h = usb_board()
        h.port_ready(timeout=1.0)
        lk = UsbLink(b, h)
        # One request of one packet each way: both bulk toggles now at DATA1.
        lk.ok(link.hello)
        box = h.control(request(h))
        while not box:
            b.run(0.0005)
        self.assertIsNone(box[0])
        for _ in range(3):
            m, _ = lk.ok(link.status, timeout=0.2)
            self.assertEqual(m["reply"], "Status")
        self.assertEqual(h.dropped, [], "no IN packet dropped for its PID")

    def test_a_repeated_set_configuration(self):
        self.scenario(lambda h: h.set_configuration())

    def test_clear_halt_on_bulk_out(self):
        self.scenario(lambda h: h.clear_halt(h.bulk_out))

    def test_clear_halt_on_bulk_in(self):
        self.scenario(lambda h: h.clear_halt(h.bulk_in))


@needs_usb
class UsbLinkTwin(test_twin.LinkTwin):
    """test_twin.LinkTwin's checks, the link over USB: from the built-in bank, a bank
    uploaded (the restart re-enumerates), played by command tick for tick against
    the host player, status requests back to back, the tick's budget meanwhile."""

    @classmethod
    def setUpClass(cls):
        SCRATCH.mkdir(parents=True, exist_ok=True)
        cls.bank = SCRATCH / "link-hot.bank"
        subprocess.run([str(CODES), "hot", "1000000", str(cls.bank)], check=True)
        cls.image = cls.bank.read_bytes()
        b, cls.otg, cls.usb = usb_board(erase=True)
        cls.board = b
        h = cls.host = UsbLink(b, cls.usb)
        cls.usb.port_ready(timeout=1.0)
        m, _ = h.ok(link.hello)
        cls.firmware = m["firmware"]
        b.count_tick_instructions()
        cls.upload_from = b.t
        cls.commit = upload(h, cls.image)
        cls.upload_until = b.t
        b.count_tick_instructions(False)
        cls.usb.port_ready(timeout=1.0)  # let the restart go by, then ask again
        h.pump(0.5)
        cls.usb.port_ready(timeout=1.0)
        cls.restarted = b.t
        b.count_tick_instructions()
        cls.play, cls.play_end = h.ok(link.play, 1)
        cls.statuses = 0
        while b.t < cls.play_end + 0.45 * twin.T_HZ:
            h.ok(link.status)
            cls.statuses += 1
        h.pump(0.15)
        b.count_tick_instructions(False)

    def test_the_restart_enumerates_again(self):
        self.assertEqual([x for _, x in self.usb.log].count("configured"), 2)
        self.assertEqual(self.otg.errors, [])
        self.assertEqual(self.usb.dropped, [])


@needs_usb
class UsbStream(test_twin.LinkStream):
    """test_twin.LinkStream's checks over USB, and a cable pulled mid-stream: the
    dead-man still takes the outputs to 0 A within its deadline and ramp."""

    def setUp(self):
        pass

    def boot(self):
        b, otg, usb = usb_board(bank=EMOJI.read_bytes())
        usb.port_ready(timeout=1.0)
        return b, UsbLink(b, usb), usb

    def test_a_vanished_host_leaves_the_outputs_at_0a(self):
        self.check_abandoned(pull=False)

    def test_a_pulled_cable_leaves_the_outputs_at_0a(self):
        self.check_abandoned(pull=True)

    def check_abandoned(self, pull):
        b, h, usb = self.boot()
        begun = b.t
        last, sent = self.stream(h, 300)
        if pull:
            last = b.t
            usb.plug(False)
        h.pump(0.2 + sent * 0.01)
        start = next((f[0] for f in b.frames if f[0] > begun and f[1][0] > 2048), None)
        self.assertIsNotNone(start, "the stream played")
        # The dead-man counts from the buffer running dry: at 0 A within the deadline
        # and the ramp after the last keyframe sent was due, cable or no cable.
        due = start + (sent - 1) * 10 * MS
        rest = next(f[0] for f in b.frames if f[0] > last and f[1] == IDLE)
        after = (rest - due) / MS
        if os.environ.get("TWIN_VERBOSE"):
            print(f"\nstream {'cable pulled' if pull else 'abandoned'}: at 0 A {(rest - last) / MS:.1f} ms "
                  f"after the last byte, {after:.1f} ms after its last keyframe was due")
        self.assertLessEqual(after, link.STREAM_DEADLINE_MS + self.RAMP_MS + 2)
        self.assertTrue(all(f[1] == IDLE for f in b.frames if f[0] >= rest))
        if pull:
            self.assertEqual(usb.state, "detached")

    def test_the_ticks_of_a_stream_stay_within_the_budget(self):
        b, h, _ = self.boot()
        b.count_tick_instructions()
        self.stream(h, 300)
        h.ok(link.stop)
        h.pump(0.1)
        b.count_tick_instructions(False)
        costs = sorted(n for _, n in b.tick_instructions)
        if os.environ.get("TWIN_VERBOSE"):
            print(f"\nstream ticks over USB: {len(costs)}, worst {costs[-1]} instructions")
        self.assertLessEqual(costs[-1], test_twin.TICK_BUDGET)
        test_twin.assert_whole_ticks(self, b, "stream over USB")

    def test_stop_ramps_a_stream_to_0a(self):
        b, h, _ = self.boot()
        self.stream(h, 300)
        m, end = h.ok(link.stop)
        self.assertEqual(m["source"], ("stream",))
        h.pump(0.1)
        rest = next(f[0] for f in b.frames if f[0] > end and f[1] == IDLE)
        self.assertLessEqual((rest - end) / MS, self.RAMP_MS + 2)


PROGRAM_S = 16e-6  # one x32 program, typical (DS8626; twin.Flash)


def timed_upload(host, image):
    """(seconds from BankBegin to the commit's reply, the flash's own seconds)."""
    b = host.b
    t0, p0 = b.t, b.programs
    commit = upload(host, image)
    assert commit["crc"] == zlib.crc32(image), commit
    programs = b.programs - p0
    erases = sum(end - start for start, end, _ in b.erases if start >= t0) / twin.T_HZ
    return (b.t - t0) / twin.T_HZ, erases + programs * PROGRAM_S


@needs_usb
class UploadTime(unittest.TestCase):
    """A 200 KB bank over USB takes at most 1.2 times what the flash itself needs to
    erase and program it: the wire is no longer the bottleneck. (USART2's time for
    the same bank: `usb_figures.py`.)"""

    def test_a_200_kb_bank(self):
        SCRATCH.mkdir(parents=True, exist_ok=True)
        big = SCRATCH / "big.bank"
        subprocess.run([str(CODES), "big", str(200 * 1024), str(big)], check=True)
        image = big.read_bytes()
        b, _, usb = usb_board(erase=True)
        usb.port_ready(timeout=1.0)
        took, own = timed_upload(UsbLink(b, usb), image)
        if os.environ.get("TWIN_VERBOSE"):
            print(f"\n{len(image)} B over USB: {took:.2f} s, the flash's own {own:.2f} s ({took / own:.2f}x)")
        self.assertLessEqual(took, 1.2 * own)


@needs_usb
class UsbStudyScript(test_twin.StudyScript):
    """test_twin.StudyScript's runs of the real `touchc`, over the twin's USB port
    on a pseudo-terminal: the study script, and an upload that restarts the sleeve
    (it enumerates again) and is verified."""

    test_the_script_is_valid_bash = None
    test_without_a_sleeve_the_script_stops_in_one_line = None

    def serving(self, board):
        if not test_twin.TOUCHC.exists():
            self.skipTest(f"{test_twin.TOUCHC} not built (run.sh builds it)")
        otg_fs.write_uid(board, UID)
        host = usb_host.UsbHost(board, board.attach(otg_fs.OtgFs(board)))
        host.plug(True)
        SCRATCH.mkdir(parents=True, exist_ok=True)
        port = SCRATCH / "sleeve-usb-pty"
        stop = threading.Event()
        server = threading.Thread(target=usb_host.serve, args=(board, host, str(port)), kwargs={"stop": stop})
        server.start()
        self.addCleanup(server.join)
        self.addCleanup(stop.set)
        deadline = time.monotonic() + 10
        while not port.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        return port


@needs_usb
class CablePulled(unittest.TestCase):
    """VBUS gone and back: the sleeve enumerates again; gone mid-upload, the bank it
    then plays is a whole one, never part old and part new."""

    def test_the_cable_out_and_in_again_enumerates_again(self):
        b, otg, usb = usb_board()
        usb.port_ready(timeout=1.0)
        lk = UsbLink(b, usb)
        lk.ok(link.hello)
        usb.plug(False)
        lk.pump(0.2)
        self.assertEqual(usb.state, "detached")
        usb.plug(True)
        lk.ok(link.hello)
        self.assertEqual([x for _, x in usb.log].count("configured"), 2)
        self.assertEqual(otg.errors, [])

    def test_pulled_mid_upload_the_sleeve_plays_a_whole_bank(self):
        SCRATCH.mkdir(parents=True, exist_ok=True)
        bank = SCRATCH / "link-hot.bank"
        subprocess.run([str(CODES), "hot", "1000000", str(bank)], check=True)
        image = bank.read_bytes()
        b, otg, usb = usb_board(erase=True)
        usb.port_ready(timeout=1.0)
        lk = UsbLink(b, usb)
        lk.ok(link.bank_begin, len(image), zlib.crc32(image), timeout=6.0)
        half = len(image) // 2 // link.MAX_CHUNK * link.MAX_CHUNK
        for off in range(0, half, link.MAX_CHUNK):
            lk.ok(link.bank_chunk, off, image[off:off + link.MAX_CHUNK])
        usb.plug(False)
        # The upload is abandoned (nothing heard for UPLOAD_IDLE_MS) and the sleeve
        # restarts on what its flash holds: not a bank (half of one), so the built-in.
        b.run(31.5)
        self.assertEqual([c for _, c in b.resets], ["SYSRESETREQ"])
        usb.plug(True)
        usb.port_ready(timeout=1.0)
        t = b.now() + 0.05
        b.press(t, test_twin.SHORT)
        b.run(0.8)
        want, _ = test_twin.expected(EMOJI, 0)
        frames = test_twin.codes(b)
        i = test_twin.first_frame_after(b, t + test_twin.SHORT)
        self.assertIsNotNone(test_twin.find(frames, want[:600], i, i + 40), "the built-in slot 0, tick for tick")


@needs_usb
class UsbPlayLatency(unittest.TestCase):
    """A `Play` whose packet the device takes anywhere in the 1 kHz period: the tick
    writes the slot's first frame within 2 ms of it."""

    def test_every_phase_of_the_tick(self):
        b, _, usb = usb_board(bank=EMOJI.read_bytes())
        usb.port_ready(timeout=1.0)
        h = UsbLink(b, usb)
        want = test_twin.expected(EMOJI, 0)[0][:300]
        written = []
        for k in range(20):
            tick = b.frames[-1][0]
            h.pump((tick + 2 * MS + k * MS // 20 - b.t) / twin.T_HZ, step=usb_host.STEP_S)
            h.seq += 1
            usb.send(link.play(h.seq, 0))
            while usb.tx:
                b.run(usb_host.STEP_S)
            end = usb.sent_at
            h.pump(0.31)
            frames = test_twin.codes(b)
            i = test_twin.first_frame_after(b, end / twin.T_HZ)
            o = test_twin.find(frames, want, i, i + 5)
            self.assertIsNotNone(o, f"phase {k}: slot 0 not on the outputs")
            written.append((b.frames[o][0] - end) / MS)
            h.ok(link.stop)
            h.pump(0.1)
        if os.environ.get("TWIN_VERBOSE"):
            print(f"\nplay over USB, its packet taken to the first frame written: "
                  f"{min(written):.3f}-{max(written):.3f} ms")
        self.assertLessEqual(max(written), 2.0, written)
