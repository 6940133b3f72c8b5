"""Writes the .npz fixtures of host/tests/it/recording.rs the way numpy's savez does.

numpy is not needed: this repeats numpy.savez's container calls with the standard
library (ZipFile with allowZip64, each member opened for writing with force_zip64=True,
stored for savez, deflated for savez_compressed) around .npy bytes built by hand in
numpy's format 1.0 (header padded to a 64-byte boundary). Run it from this directory;
the files are committed, so the tests need no Python.
"""

import io
import struct
import zipfile


def npy(descr, shape, payload):
    header = "{'descr': '%s', 'fortran_order': False, 'shape': %s, }" % (descr, shape)
    header += " " * (63 - (10 + len(header)) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode() + payload


def savez(path, members, compression, stream=False):
    """numpy.lib._npyio_impl._savez, minus the arrays."""
    target = io.BytesIO()
    out = target
    if stream:
        # A pipe: zipfile cannot seek back, so it writes data descriptors.
        class Pipe(io.RawIOBase):
            def writable(self):
                return True

            def write(self, b):
                return target.write(b)

        out = Pipe()
    with zipfile.ZipFile(out, mode="w", compression=compression, allowZip64=True) as z:
        for key, data in members:
            info = zipfile.ZipInfo(key + ".npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = compression
            with z.open(info, "w", force_zip64=True) as fid:
                fid.write(data)
    with open(path, "wb") as f:
        f.write(target.getvalue())


# pressure[t, r, c] = t + r / 10 + c / 100 as float32, NaN at (r, c) = (0, 0).
T, R, C = 45, 3, 4
values = []
for t in range(T):
    for r in range(R):
        for c in range(C):
            values.append(float("nan") if (r, c) == (0, 0) else t + r / 10 + c / 100)
pressure = npy("<f4", "(%d, %d, %d)" % (T, R, C), struct.pack("<%df" % len(values), *values))
rate = npy("<f8", "()", struct.pack("<d", 54.0))
pitch = npy("<i8", "()", struct.pack("<q", 25))

savez("savez.npz", [("pressure", pressure), ("rate_hz", rate), ("pitch_mm", pitch)],
      zipfile.ZIP_STORED)
savez("savez_compressed.npz", [("pressure", pressure), ("rate_hz", rate)],
      zipfile.ZIP_DEFLATED)
savez("streamed.npz", [("pitch_mm", npy(">f4", "()", struct.pack(">f", 8.5))),
                       ("pressure", pressure)], zipfile.ZIP_DEFLATED, stream=True)
