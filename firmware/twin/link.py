"""The sleeve link's frames (protocol/SPEC.md, "Link"), for the twin's tests: the
few requests they send, and the device's messages read back as dicts.

Written from the SPEC, not from the Rust code: the tests pin it to the SPEC's own
example bytes, so a twin test that passes speaks the documented protocol.
"""

import struct
import zlib

VERSION = 1
MAX_CHUNK = 256
STREAM_DEADLINE_MS = 50
COMMANDS = ["Hello", "Info", "Slot", "Status", "BankRead", "BankBegin", "BankChunk", "BankCommit",
            "BankAbort", "Play", "Stop", "StreamBegin", "StreamData", "StreamEnd"]
EVENTS = ["Button", "Started", "Stopping", "Finished", "LimitHit", "TooHot", "Selected", "BadSlot",
          "StreamStopped"]
ERRORS = ["Malformed", "UnsupportedVersion", "NoSuchSlot", "BadSlot", "TooHot", "Busy", "NoBank", "NoUpload",
          "OutOfOrder", "OutOfRange", "BadCrc", "WrongLayout", "BadBank", "Flash", "NoStream", "StreamGap",
          "StreamFull", "QueueFull"]
FRAME_ERRORS = ["TooLong", "Cobs", "Short", "BadCrc", "Malformed", "Overrun"]


# ------------------------------------------------------------------ encoding


def varint(n):
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        out.append(b | (0x80 if n else 0))
        if not n:
            return bytes(out)


def blob(b):
    return varint(len(b)) + bytes(b)


def cobs(data):
    out, block = bytearray(), bytearray()
    for b in data:
        if b == 0:
            out += bytes([len(block) + 1]) + block
            block = bytearray()
        else:
            block.append(b)
            if len(block) == 254:
                out += b"\xff" + block
                block = bytearray()
    out += bytes([len(block) + 1]) + block
    return bytes(out)


def frame(message):
    """A message's bytes as they go on the wire: COBS(message ++ CRC-32 LE) 00."""
    return cobs(message + struct.pack("<I", zlib.crc32(message))) + b"\0"


def request(seq, command, *fields):
    """A request frame: `fields` already encoded (see the helpers below)."""
    return frame(varint(seq) + varint(COMMANDS.index(command)) + b"".join(fields))


def hello(seq):
    return request(seq, "Hello", varint(VERSION))


def play(seq, slot):
    return request(seq, "Play", bytes([slot]))


def stop(seq):
    return request(seq, "Stop")


def status(seq):
    return request(seq, "Status")


def bank_begin(seq, length, crc):
    return request(seq, "BankBegin", varint(length), varint(crc))


def bank_chunk(seq, offset, data):
    return request(seq, "BankChunk", varint(offset), blob(data))


def bank_commit(seq):
    return request(seq, "BankCommit")


def stream_begin(seq, period_ms, ramp_ms, full_scale_ma, limits):
    """`limits`: (peak mA, slew mA/ms, continuous mA, I^2 t budget mA^2 s)."""
    return request(seq, "StreamBegin", varint(period_ms), varint(ramp_ms), varint(full_scale_ma),
                   b"".join(varint(v) for v in limits))


def stream_data(seq, index, keyframes):
    """`keyframes`: lists of eight Q15 values."""
    payload = b"".join(struct.pack("<8h", *k) for k in keyframes)
    return request(seq, "StreamData", varint(index), blob(payload))


def stream_end(seq):
    return request(seq, "StreamEnd")


# ------------------------------------------------------------------ decoding


class Reader:
    def __init__(self, data):
        self.data, self.at = data, 0

    def u8(self):
        self.at += 1
        return self.data[self.at - 1]

    def var(self):
        n = shift = 0
        while True:
            b = self.u8()
            n |= (b & 0x7F) << shift
            shift += 7
            if not b & 0x80:
                return n

    def blob(self):
        n = self.var()
        self.at += n
        return bytes(self.data[self.at - n:self.at])

    def source(self):
        return ("slot", self.u8()) if self.var() == 0 else ("stream",)


def uncobs(data):
    out, i = bytearray(), 0
    while i < len(data):
        code = data[i]
        if code == 0 or i + code > len(data):
            raise ValueError("not COBS")
        out += data[i + 1:i + code]
        i += code
        if code != 0xFF and i < len(data):
            out.append(0)
    return bytes(out)


def parse(frame_bytes):
    """A device message from one frame (without its 00) as a dict: `kind` (reply,
    refused, event, unreadable), and `seq`, `reply`/`error`/`event`, `tick` and the
    fields the tests read."""
    raw = uncobs(frame_bytes)
    body, crc = raw[:-4], struct.unpack("<I", raw[-4:])[0]
    if zlib.crc32(body) != crc:
        raise ValueError("CRC mismatch")
    r = Reader(body)
    kind = r.var()
    if kind == 0:
        m = {"kind": "reply", "seq": r.var()}
        name = COMMANDS[r.var()]
        m["reply"] = name
        if name == "Hello":
            m["version"], m["firmware"] = r.var(), r.blob().decode()
        elif name == "BankBegin":
            m["len"] = r.var()
        elif name == "BankChunk":
            m["next"] = r.var()
        elif name == "BankCommit":
            m["crc"], m["slots"] = r.var(), r.u8()
        elif name == "Play":
            m["slot"], m["tick"], m["now"] = r.u8(), r.var(), bool(r.u8())
        elif name == "Stop":
            m["source"] = r.source() if r.u8() else None
            m["tick"] = r.var()
        elif name == "Status":
            m["tick"] = r.var()
            m["playing"] = r.source() if r.u8() else None
        elif name == "StreamBegin":
            m["capacity"] = r.var()
        elif name == "StreamData":
            m["next"], m["room"] = r.var(), r.var()
        return m
    if kind == 1:
        return {"kind": "refused", "seq": r.var(), "error": ERRORS[r.var()]}
    if kind == 2:
        m = {"kind": "event", "tick": r.var(), "event": EVENTS[r.var()]}
        if m["event"] in ("Started", "Stopping", "Finished"):
            m["source"] = r.source()
        return m
    return {"kind": "unreadable", "error": FRAME_ERRORS[r.var()]}


class Stream:
    """Splits the device's bytes into messages at each 00."""

    def __init__(self):
        self.buf = bytearray()

    def feed(self, data):
        out = []
        for b in data:
            if b == 0:
                if self.buf:
                    out.append(parse(bytes(self.buf)))
                self.buf = bytearray()
            else:
                self.buf.append(b)
        return out
