#!/usr/bin/env python3
"""A rosbag2 recording of a survey as the ROS 2 drivers would have made it, written by
independent writers: PyPI `rosbags` 0.11.9 (CDR, the rosbag2 folder with metadata.yaml, MCAP or
sqlite3 storage) and, for chunk-compressed MCAP, PyPI `mcap` (Foxglove's writer).

From a survey folder (`spherecal synth`: lidar.pcap + ins.bin, a VN-200 binary stream):
- every Velodyne data packet (UDP 2368) into `velodyne_msgs/msg/VelodyneScan` messages of
  --scan-packets packets (the driver's npackets: 76 for a VLP-16 at 600 rpm), each packet
  stamped with its capture time (the driver's host time); the position packets are dropped
  (the driver does not record them);
- every VN-200 binary frame with a valid CRC (Common group only) into a
  `vectornav_msgs/msg/CommonGroup`, stamped with its GPS time as Unix time plus --ins-lag;
  with --sigmas also an `InsGroup` (posu) and `AttitudeGroup` (ypru) per frame.
The frames are parsed here, independently of spherecal (VN-200 user manual, binary output).

With --clouds the scans are written instead as velodyne_pointcloud would publish them:
`sensor_msgs/msg/PointCloud2` (PointcloudXYZIRT: x y z intensity float32, ring uint16, time
float32 after the cloud's stamp), decoded here from the VLP-16 manual (section 9, single return)
with the driver's conventions (VLP16db.yaml's vertical offsets): the ROS frame (x forward, y left), the azimuth interpolated per
firing and rounded to 0.01 deg, ring in order of elevation, returns inside min_range 0.9 m or
beyond 130 m dropped, each point's time = its packet's stamp + its firing offset - the stamp.

Usage: ros2-bag.py SURVEY OUT [--storage mcap|sqlite3|mcap-zstd|mcap-lz4] [--humble] [--extra]
       [--sigmas] [--scan-packets N] [--lidar-topic T] [--ins-topic T] [--max-scans N]
       [--drop-ins-every N] [--garble-ins-every N]
OUT is a bag folder for mcap/sqlite3 (rosbags) and a single .mcap file for mcap-zstd/-lz4.
--humble rewrites the sqlite3 tables to Humble's schema (no type_description_hash, no
message_definitions). --extra adds unrelated topics (/rosout-like strings, a TimeGroup)."""
import argparse, os, sqlite3, struct, sys
import numpy as np
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

sys.path.insert(0, os.path.dirname(__file__))
exec(open(os.path.join(os.path.dirname(__file__), "ros2-vectors.py")).read().split("types = {}")[0])  # defs
ts = get_typestore(Stores.ROS2_HUMBLE)
types = {}
for name, text in defs.items():
    types.update(get_types_from_msg(text, name))
ts.register(types)
T = lambda n: ts.types[n]
Time, Header = T("builtin_interfaces/msg/Time"), T("std_msgs/msg/Header")
V3, P3, Q = T("geometry_msgs/msg/Vector3"), T("geometry_msgs/msg/Point"), T("geometry_msgs/msg/Quaternion")
GPS_UNIX = 315964800
LEAP = 18


def stamp(ns):
    return Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))


def pcap_packets(path):
    """(time ns, payload) of every UDP datagram to port 2368 (classic pcap, Ethernet)."""
    b = open(path, "rb").read()
    magic = b[:4]
    if magic in (b"\xd4\xc3\xb2\xa1", b"\x4d\x3c\xb2\xa1"):
        e = "<"
    elif magic in (b"\xa1\xb2\xc3\xd4", b"\xa1\xb2\x3c\x4d"):
        e = ">"
    else:
        sys.exit(f"{path}: not a classic pcap")
    nano = magic in (b"\x4d\x3c\xb2\xa1", b"\xa1\xb2\x3c\x4d")
    link = struct.unpack(e + "I", b[20:24])[0]
    at = 24
    while at + 16 <= len(b):
        sec, frac, incl, _ = struct.unpack(e + "IIII", b[at:at + 16])
        rec = b[at + 16:at + 16 + incl]
        at += 16 + incl
        if len(rec) < incl:
            break
        ip = rec[14:] if link == 1 else rec
        if link == 1 and rec[12:14] != b"\x08\x00":
            continue
        ihl = (ip[0] & 15) * 4
        if ip[9] != 17:
            continue
        udp = ip[ihl:]
        dport, ulen = struct.unpack(">HH", udp[2:6])
        if dport != 2368:
            continue
        t = sec * 1_000_000_000 + (frac if nano else frac * 1000)
        yield t, udp[8:ulen]


COMMON_SIZES = [8, 8, 8, 12, 16, 12, 24, 12, 12, 24, 20, 28, 2, 4, 8]


def crc16(data):
    crc = 0
    for c in data:
        crc = ((crc >> 8) | (crc << 8)) & 0xFFFF
        crc ^= c
        crc ^= (crc & 0xFF) >> 4
        crc ^= (crc << 12) & 0xFFFF
        crc ^= ((crc & 0xFF) << 5) & 0xFFFF
    return crc


# Sizes of the Attitude and INS group fields the boards configure: YprU (Attitude bit 8),
# PosU (INS bit 9); a frame with any other field of those groups is left out.
OTHER_SIZES = {4: {8: 12}, 5: {9: 4}}


def vn200_frames(path):
    """Dicts of the Common-group fields of every VN-200 binary frame with a good CRC (groups
    Common, and the Attitude and INS groups' YprU and PosU, which are skipped)."""
    b = open(path, "rb").read()
    i = 0
    while i < len(b) - 4:
        groups = b[i + 1] if b[i] == 0xFA else 0
        if not groups & 1 or groups & ~0x31:
            i += 1
            continue
        extra = [g for g in (4, 5) if groups >> g & 1]
        head = 2 + 2 * (1 + len(extra))
        if i + head > len(b):
            break
        mask = struct.unpack("<H", b[i + 2:i + 4])[0]
        sizes = []
        for k, g in enumerate(extra):
            m = struct.unpack("<H", b[i + 4 + 2 * k:i + 6 + 2 * k])[0]
            bits = [j for j in range(16) if m >> j & 1]
            if any(j not in OTHER_SIZES[g] for j in bits):
                sizes = None
                break
            sizes += [OTHER_SIZES[g][j] for j in bits]
        if mask & 0x8000 or sizes is None:
            i += 1
            continue
        n = sum(COMMON_SIZES[k] for k in range(15) if mask >> k & 1) + sum(sizes)
        end = i + head + n + 2
        if end > len(b) or crc16(b[i + 1:end]) != 0:
            i += 1
            continue
        f, at = {"mask": mask}, i + head
        for k in range(15):
            if mask >> k & 1:
                f[k] = b[at:at + COMMON_SIZES[k]]
                at += COMMON_SIZES[k]
        yield f
        i = end


def common_group(f, lag_ns):
    m = f["mask"]
    tg = struct.unpack("<Q", f[1])[0] if 1 in f else 0
    ypr = struct.unpack("<3f", f[3]) if 3 in f else (0.0, 0.0, 0.0)
    q = struct.unpack("<4f", f[4]) if 4 in f else (0.0, 0.0, 0.0, 1.0)
    lla = struct.unpack("<3d", f[6]) if 6 in f else (0.0, 0.0, 0.0)
    st = struct.unpack("<H", f[12])[0] if 12 in f else 0
    host = tg + (GPS_UNIX - LEAP) * 1_000_000_000 + lag_ns
    ts = struct.unpack("<Q", f[0])[0] if 0 in f else 0
    fields = sum(1 << k for k in (0, 1, 3, 4, 6, 12) if m >> k & 1)
    status = T("vectornav_msgs/msg/InsStatus")(mode=st & 3, gps_fix=bool(st & 4), time_error=bool(st & 16),
        imu_error=bool(st & 32), mag_pres_error=bool(st & 64), gps_error=bool(st & 128),
        gps_heading_ins=bool(st & 256), gps_compass=bool(st & 512))
    z = V3(x=0.0, y=0.0, z=0.0)
    msg = T("vectornav_msgs/msg/CommonGroup")(header=Header(stamp=stamp(host), frame_id="vectornav"),
        group_fields=fields, timestartup=ts, timegps=tg, timesyncin=0,
        yawpitchroll=V3(x=float(ypr[0]), y=float(ypr[1]), z=float(ypr[2])),
        quaternion=Q(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])), angularrate=z,
        position=P3(x=lla[0], y=lla[1], z=lla[2]), velocity=z, accel=z, imu_accel=z, imu_rate=z, magpres_mag=z,
        magpres_temp=0.0, magpres_pres=0.0, deltatheta_dtime=0.0, deltatheta_dtheta=z, deltatheta_dvel=z,
        insstatus=status, syncincnt=0, timegpspps=0)
    return host, msg, status


VLP16_ELEV = [-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15]
VLP16_VERT_OFFSET = [0.0112, -0.0007, 0.0097, -0.0022, 0.0081, -0.0037, 0.0066, -0.0051,
                     0.0051, -0.0066, 0.0037, -0.0081, 0.0022, -0.0097, 0.0007, -0.0112]  # VLP16db.yaml
VLP16_RING = [(l // 2) if l % 2 == 0 else 8 + l // 2 for l in range(16)]


def qmul(a, b):
    """Hamilton product, quaternions as (x, y, z, w) (tf2's)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def quat_ypr(yaw, pitch, roll):
    """The FRD-to-NED quaternion (x, y, z, w) of a 3-2-1 yaw, pitch, roll [deg]."""
    import math
    h = [math.radians(v) / 2 for v in (yaw, pitch, roll)]
    qz = (0.0, 0.0, math.sin(h[0]), math.cos(h[0]))
    qy = (0.0, math.sin(h[1]), 0.0, math.cos(h[1]))
    qx = (math.sin(h[2]), 0.0, 0.0, math.cos(h[2]))
    return qmul(qmul(qz, qy), qx)


def cloud_of(packets, stamp_ns, min_range=0.9, max_range=130.0):
    """A PointCloud2 (XYZIRT) of VLP-16 data packets [(stamp ns, 1206 bytes)], stamped stamp_ns."""
    raw = np.frombuffer(b"".join(p for _, p in packets), dtype=np.uint8).reshape(len(packets), 1206)
    blocks = raw[:, :1200].reshape(-1, 12, 100)
    if not (blocks[:, :, 0:2] == [0xFF, 0xEE]).all():
        sys.exit("--clouds: a data block without its 0xFFEE flag (only single-return VLP-16 packets are converted)")
    if not (raw[:, 1205] == 0x22).all() or not (raw[:, 1204] == 0x37).all():
        sys.exit("--clouds: only VLP-16 (product 0x22) packets in strongest-return mode are converted")
    az = blocks[:, :, 2].astype(np.int64) | (blocks[:, :, 3].astype(np.int64) << 8)
    diff = (np.roll(az, -1, axis=1) - az + 36000) % 36000
    diff[:, 11] = diff[:, 10]  # the last block: the previous block's step
    ch = blocks[:, :, 4:].reshape(-1, 12, 32, 3)
    dist = (ch[..., 0].astype(np.int64) | (ch[..., 1].astype(np.int64) << 8)) * 0.002
    inten = ch[..., 2].astype(np.float32)
    c = np.arange(32)
    firing, dsr = c // 16, c % 16
    frac = (dsr * 2.304 + firing * 55.296) / 110.592
    azc = np.round(az[:, :, None] + diff[:, :, None] * frac[None, None, :]).astype(np.int64) % 36000
    rot = np.radians(azc * 0.01)
    vert = np.radians(np.array(VLP16_ELEV, dtype=np.float64))[dsr]
    off = np.array(VLP16_VERT_OFFSET)[dsr]
    xy = dist * np.cos(vert) - off * np.sin(vert)
    x = (xy * np.cos(rot)).astype(np.float32)       # ROS x = the manual's y (forward)
    y = (-(xy * np.sin(rot))).astype(np.float32)    # ROS y = -the manual's x (left)
    z = (dist * np.sin(vert) + off * np.cos(vert)).astype(np.float32)
    ring = np.array(VLP16_RING, dtype=np.uint16)[dsr] * np.ones_like(dist, dtype=np.uint16)
    stamps = np.array([t for t, _ in packets], dtype=np.int64)
    toff = (np.arange(12)[:, None] * 110.592 + firing[None, :] * 55.296 + dsr[None, :] * 2.304) * 1e-6
    t = ((stamps - stamp_ns)[:, None, None] * 1e-9 + toff[None, :, :]).astype(np.float32)
    keep = (dist >= min_range) & (dist <= max_range)
    n = int(keep.sum())
    rec = np.zeros(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<u2"), ("time", "<f4")])
    for k, v in [("x", x), ("y", y), ("z", z), ("intensity", inten), ("ring", ring), ("time", t)]:
        rec[k] = v[keep]
    PF = T("sensor_msgs/msg/PointField")
    fields = [PF(name=k, offset=o, datatype=d, count=1) for k, o, d in
              [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7), ("ring", 16, 4), ("time", 18, 7)]]
    return T("sensor_msgs/msg/PointCloud2")(header=Header(stamp=stamp(stamp_ns), frame_id="velodyne"),
        height=1, width=n, fields=fields, is_bigendian=False, point_step=22, row_step=22 * n,
        data=np.frombuffer(rec.tobytes(), dtype=np.uint8), is_dense=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("survey")
    ap.add_argument("out")
    ap.add_argument("--storage", default="mcap", choices=["mcap", "sqlite3", "mcap-zstd", "mcap-lz4"])
    ap.add_argument("--humble", action="store_true")
    ap.add_argument("--extra", action="store_true")
    ap.add_argument("--sigmas", action="store_true")
    ap.add_argument("--scan-packets", type=int, default=76)
    ap.add_argument("--lidar-topic", default="/velodyne_packets")
    ap.add_argument("--ins-topic", default="/vectornav/raw/common")
    ap.add_argument("--ins-lag", type=float, default=0.002)
    ap.add_argument("--max-scans", type=int, default=0)
    ap.add_argument("--ins-margin", type=float, default=2.0, help="with --max-scans: INS this long [s] around the scans")
    ap.add_argument("--no-ins", action="store_true", help="leave the INS out")
    ap.add_argument("--ins-as-imu", action="store_true",
                    help="the INS as sensor_msgs Imu + NavSatFix only (no GPS time, no INS mode)")
    ap.add_argument("--clouds", action="store_true",
                    help="the LiDAR as velodyne_pointcloud's PointCloud2 (XYZIRT) on /velodyne_points")
    ap.add_argument("--time-ref", action="store_true",
                    help="with --ins-as-imu: also the driver's TimeReference topics (time_gps, time_startup) and imu_uncompensated")
    ap.add_argument("--imu-ned", action="store_true",
                    help="with --ins-as-imu: the driver's use_enu false (the sensor's FRD/NED quaternion and force)")
    ap.add_argument("--pcap", help="the capture (default: SURVEY/lidar.pcap)")
    ap.add_argument("--expect", help="write what was put in (packets, first INS samples) as JSON here")
    ap.add_argument("--drop-ins-every", type=int, default=0,
                    help="leave out every Nth CommonGroup message (a recorder dropping messages)")
    ap.add_argument("--garble-ins-every", type=int, default=0,
                    help="cut every Nth CommonGroup message's CDR short (a message no reader can parse)")
    a = ap.parse_args()
    expect = {"packets": [], "ins": []}

    msgs = []  # (log time, topic, type, cdr)
    pk, scans = [], 0
    Pkt, Scan = T("velodyne_msgs/msg/VelodynePacket"), T("velodyne_msgs/msg/VelodyneScan")

    def flush():
        nonlocal pk, scans
        if pk:
            t = pk[-1].stamp.sec * 1_000_000_000 + pk[-1].stamp.nanosec
            if a.clouds:
                c = cloud_of([(p.stamp.sec * 1_000_000_000 + p.stamp.nanosec, p.data.tobytes()) for p in pk], t)
                msgs.append((t, "/velodyne_points" if a.lidar_topic == "/velodyne_packets" else a.lidar_topic,
                             "sensor_msgs/msg/PointCloud2", ts.serialize_cdr(c, "sensor_msgs/msg/PointCloud2")))
            else:
                s = Scan(header=Header(stamp=pk[-1].stamp, frame_id="velodyne"), packets=pk)
                msgs.append((t, a.lidar_topic, "velodyne_msgs/msg/VelodyneScan", ts.serialize_cdr(s, "velodyne_msgs/msg/VelodyneScan")))
            scans += 1
        pk = []

    for t, payload in pcap_packets(a.pcap or os.path.join(a.survey, "lidar.pcap")):
        if a.max_scans and scans >= a.max_scans:
            break
        pk.append(Pkt(stamp=stamp(t), data=np.frombuffer(payload, dtype=np.uint8)))
        expect["packets"].append([t, sum(payload) % (1 << 32), payload[:8].hex()])
        if len(pk) == a.scan_packets:
            flush()
    flush()
    first, last = msgs[0][0], msgs[-1][0]
    n_ins = 0
    ins_bin = os.path.join(a.survey, "ins.bin")
    for f in ([] if a.no_ins and not os.path.exists(ins_bin) else vn200_frames(ins_bin)):
        host, msg, status = common_group(f, int(a.ins_lag * 1e9))
        if a.max_scans and not (first - a.ins_margin * 1e9 <= host <= last + a.ins_margin * 1e9):
            continue
        if a.no_ins:
            continue
        if a.ins_as_imu:
            # As dawonn/vectornav's vn_sensor_msgs publishes them from the group (the same
            # header): Imu (the attitude quaternion; with its default use_enu, RFU body to ENU:
            # q_ned2enu * q_frd2ned * q_rfu2frd, the specific force in RFU), NavSatFix (the INS
            # position, status from the fix), TimeReference vectornav/time_gps (time_ref = the
            # group's GPS time). The quaternion is made here from the frame's yaw, pitch, roll.
            ypr = [float(v) for v in struct.unpack("<3f", f[3])] if 3 in f else [0.0, 0.0, 0.0]
            q = quat_ypr(*ypr)
            if a.imu_ned:
                orient, acc = q, V3(x=0.0, y=0.0, z=-9.81)
            else:
                c = (2 ** -0.5, 2 ** -0.5, 0.0, 0.0)
                orient, acc = qmul(qmul(c, q), c), V3(x=0.0, y=0.0, z=9.81)
            imu = T("sensor_msgs/msg/Imu")(header=msg.header,
                orientation=Q(x=orient[0], y=orient[1], z=orient[2], w=orient[3]),
                orientation_covariance=np.zeros(9), angular_velocity=V3(x=0.0, y=0.0, z=0.0),
                angular_velocity_covariance=np.zeros(9), linear_acceleration=acc,
                linear_acceleration_covariance=np.zeros(9))
            msgs.append((host, "/vectornav/imu", "sensor_msgs/msg/Imu", ts.serialize_cdr(imu, "sensor_msgs/msg/Imu")))
            if a.time_ref:
                # The uncompensated IMU (another Imu topic, spherecal must choose */imu).
                msgs.append((host, "/vectornav/imu_uncompensated", "sensor_msgs/msg/Imu", ts.serialize_cdr(imu, "sensor_msgs/msg/Imu")))
            fix = T("sensor_msgs/msg/NavSatFix")(header=msg.header,
                status=T("sensor_msgs/msg/NavSatStatus")(status=0 if msg.insstatus.gps_fix else -1, service=1),
                latitude=msg.position.x, longitude=msg.position.y, altitude=msg.position.z,
                position_covariance=np.zeros(9), position_covariance_type=2)
            msgs.append((host, "/vectornav/gnss", "sensor_msgs/msg/NavSatFix", ts.serialize_cdr(fix, "sensor_msgs/msg/NavSatFix")))
            if a.time_ref:
                TR = T("sensor_msgs/msg/TimeReference")
                for topic, ref, src in [("/vectornav/time_gps", msg.timegps, "gps"), ("/vectornav/time_startup", 12345, "startup")]:
                    tr = TR(header=msg.header, time_ref=stamp(ref), source=src)
                    msgs.append((host, topic, "sensor_msgs/msg/TimeReference", ts.serialize_cdr(tr, "sensor_msgs/msg/TimeReference")))
            n_ins += 1
            continue
        if len(expect["ins"]) < 5:
            expect["ins"].append({"host": host, "timegps": msg.timegps,
                "ypr": [msg.yawpitchroll.x, msg.yawpitchroll.y, msg.yawpitchroll.z],
                "lla": [msg.position.x, msg.position.y, msg.position.z], "status": msg.insstatus.mode})
        n_ins += 1
        if a.drop_ins_every and n_ins % a.drop_ins_every == 0:
            continue
        cdr = ts.serialize_cdr(msg, "vectornav_msgs/msg/CommonGroup")
        if a.garble_ins_every and n_ins % a.garble_ins_every == 1:
            cdr = cdr[:40]
        msgs.append((host, a.ins_topic, "vectornav_msgs/msg/CommonGroup", cdr))
        if a.sigmas:
            z, zp = V3(x=0.0, y=0.0, z=0.0), P3(x=0.0, y=0.0, z=0.0)
            ig = T("vectornav_msgs/msg/InsGroup")(header=msg.header, group_fields=0x0200, insstatus=status,
                poslla=zp, posecef=zp, velbody=z, velned=z, velecef=z, magecef=z, accelecef=z, linearaccelecef=z,
                posu=0.03, velu=0.05)
            msgs.append((host, "/vectornav/raw/ins", "vectornav_msgs/msg/InsGroup", ts.serialize_cdr(ig, "vectornav_msgs/msg/InsGroup")))
            ag = T("vectornav_msgs/msg/AttitudeGroup")(header=msg.header, group_fields=0x0100,
                vpestatus=T("vectornav_msgs/msg/VpeStatus")(attitude_quality=0, gyro_saturation=False, gyro_saturation_recovery=False,
                    mag_disturbance=0, mag_saturation=False, acc_disturbance=0, acc_saturation=False, known_mag_disturbance=False,
                    known_accel_disturbance=False),
                yawpitchroll=z, quaternion=Q(x=0.0, y=0.0, z=0.0, w=1.0), dcm=np.zeros(9, dtype=np.float32),
                magned=z, accelned=z, linearaccelbody=z, linearaccelned=z, ypru=V3(x=0.2, y=0.02, z=0.02))
            msgs.append((host, "/vectornav/raw/attitude", "vectornav_msgs/msg/AttitudeGroup", ts.serialize_cdr(ag, "vectornav_msgs/msg/AttitudeGroup")))
    if a.extra:
        S = T("std_msgs/msg/String")
        for k in range(0, 50):
            t = first + k * 100_000_000
            msgs.append((t, "/chatter", "std_msgs/msg/String", ts.serialize_cdr(S(data=f"hello {k}"), "std_msgs/msg/String")))
    msgs.sort(key=lambda m: m[0])
    if a.expect:
        import json
        expect["scans"], expect["ins_messages"], expect["messages"] = scans, n_ins, len(msgs)
        json.dump(expect, open(a.expect, "w"), indent=0)

    if a.storage in ("mcap", "sqlite3"):
        from rosbags.rosbag2 import StoragePlugin, Writer
        plugin = StoragePlugin.MCAP if a.storage == "mcap" else StoragePlugin.SQLITE3
        with Writer(a.out, version=9, storage_plugin=plugin) as w:
            conns = {}
            for t, topic, typ, data in msgs:
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, typ, typestore=ts)
                w.write(conns[topic], t, data)
        if a.humble and a.storage == "sqlite3":
            db = [os.path.join(a.out, f) for f in os.listdir(a.out) if f.endswith(".db3")][0]
            c = sqlite3.connect(db)
            c.execute("ALTER TABLE topics DROP COLUMN type_description_hash")
            c.execute("DROP TABLE IF EXISTS message_definitions")
            c.commit()
            c.close()
    else:
        from mcap.writer import CompressionType, Writer
        comp = CompressionType.ZSTD if a.storage == "mcap-zstd" else CompressionType.LZ4
        with open(a.out, "wb") as fh:
            w = Writer(fh, compression=comp, chunk_size=1 << 20)
            w.start(profile="ros2", library="mcap-python (spherecal test bag)")
            chans = {}
            for t, topic, typ, data in msgs:
                if topic not in chans:
                    sid = w.register_schema(name=typ, encoding="ros2msg", data=defs.get(typ, "").encode())
                    chans[topic] = w.register_channel(topic=topic, message_encoding="cdr", schema_id=sid)
                w.add_message(chans[topic], log_time=t, data=data, publish_time=t)
            w.finish()
    print(f"{a.out}: {scans} {'clouds' if a.clouds else 'scans'}, {n_ins} INS samples ({'Imu + NavSatFix' if a.ins_as_imu else 'CommonGroup'}), {len(msgs)} messages ({a.storage})")


main()
