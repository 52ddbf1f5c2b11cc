#!/usr/bin/env python3
"""The reference for `spherecal decode CAPTURE --metadata META`: every return of an Ouster
capture as Ouster's own SDK (PyPI ouster-sdk) decodes it, one line per return:
`frame_id measurement_id channel return x y z range_mm` (x y z in the sensor frame [m]).

usage: ouster_xyz.py CAPTURE.pcap META.json > OUT.txt
"""
import sys

import numpy as np
from ouster.sdk import core, open_source


def main(pcap, meta):
    src = open_source(pcap, meta=[meta], index=False, collate=False)
    info = src.sensor_info[0]
    lut = core.XYZLut(info, use_extrinsics=False)
    fields = [(core.ChanField.RANGE, "first")]
    out = sys.stdout
    for scans in src:
        for scan in scans:
            if scan is None:
                continue
            if core.ChanField.RANGE2 in scan.fields:
                fields = [(core.ChanField.RANGE, "first"), (core.ChanField.RANGE2, "second")]
            for field, name in fields:
                rng = scan.field(field)
                xyz = lut(rng)
                valid = scan.status & 1
                for m in np.nonzero(valid)[0]:
                    for ch in np.nonzero(rng[:, m])[0]:
                        x, y, z = xyz[ch, m]
                        out.write(
                            f"{scan.frame_id} {m} {ch} {name} {x:.6f} {y:.6f} {z:.6f} {rng[ch, m]}\n"
                        )


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
