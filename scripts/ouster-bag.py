#!/usr/bin/env python3
"""An Ouster capture as ouster-ros records it, written by an independent writer (PyPI `rosbags`
0.11.9): every UDP datagram to the lidar port (and the IMU port) of a classic pcap into an
`ouster_sensor_msgs/msg/PacketMsg` (`uint8[] buf`) on /ouster/lidar_packets (/ouster/imu_packets),
stamped with its capture time. ouster-ros sizes `buf` one byte longer than the packet
(`buf.resize(pf.lidar_packet_size + 1)`): so does this, the last byte 0 (--exact: no extra byte).

Usage: ouster-bag.py CAPTURE.pcap OUT [--lidar-port 7502] [--imu-port 7503]
       [--storage sqlite3|mcap] [--exact]"""
import argparse, struct, sys
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

TYPE = "ouster_sensor_msgs/msg/PacketMsg"


def datagrams(path):
    """(time ns, destination port, payload) of every whole UDP datagram (classic pcap, Ethernet)."""
    b = open(path, "rb").read()
    magic = b[:4]
    if magic in (b"\xd4\xc3\xb2\xa1", b"\x4d\x3c\xb2\xa1"):
        e = "<"
    elif magic in (b"\xa1\xb2\xc3\xd4", b"\xa1\xb2\x3c\x4d"):
        e = ">"
    else:
        sys.exit(f"{path}: not a classic pcap")
    nano = magic in (b"\x4d\x3c\xb2\xa1", b"\xa1\xb2\x3c\x4d")
    at = 24
    while at + 16 <= len(b):
        sec, frac, incl, _ = struct.unpack(e + "IIII", b[at:at + 16])
        rec = b[at + 16:at + 16 + incl]
        at += 16 + incl
        if len(rec) < incl or rec[12:14] != b"\x08\x00":
            continue
        ip = rec[14:]
        if ip[9] != 17 or struct.unpack(">H", ip[6:8])[0] & 0x3FFF:
            continue  # not UDP, or a fragment
        udp = ip[(ip[0] & 15) * 4:]
        dport, ulen = struct.unpack(">HH", udp[2:6])
        yield sec * 1_000_000_000 + (frac if nano else frac * 1000), dport, udp[8:ulen]


def main():
    p = argparse.ArgumentParser()
    p.add_argument("capture")
    p.add_argument("out")
    p.add_argument("--lidar-port", type=int, default=7502)
    p.add_argument("--imu-port", type=int, default=7503)
    p.add_argument("--storage", default="sqlite3", choices=["sqlite3", "mcap"])
    p.add_argument("--exact", action="store_true")
    a = p.parse_args()
    ts = get_typestore(Stores.ROS2_HUMBLE)
    ts.register(get_types_from_msg("uint8[] buf\n", TYPE))
    Msg = ts.types[TYPE]
    import numpy as np
    topics = {a.lidar_port: "/ouster/lidar_packets", a.imu_port: "/ouster/imu_packets"}
    plugin = StoragePlugin.MCAP if a.storage == "mcap" else StoragePlugin.SQLITE3
    n = 0
    with Writer(a.out, version=9, storage_plugin=plugin) as w:
        conns = {}
        for t, port, payload in datagrams(a.capture):
            topic = topics.get(port)
            if topic is None:
                continue
            if topic not in conns:
                conns[topic] = w.add_connection(topic, TYPE, typestore=ts)
            buf = payload if a.exact else payload + b"\x00"
            msg = Msg(buf=np.frombuffer(buf, dtype=np.uint8))
            w.write(conns[topic], t, ts.serialize_cdr(msg, TYPE))
            n += 1
    print(f"{n} packets")


if __name__ == "__main__":
    main()
