#!/usr/bin/env python3
"""Test vectors for the core's ROS 2 message views (src/ros2): messages of the ROS 2 Velodyne
and VectorNav drivers serialised to CDR by an independent writer, the PyPI `rosbags` library
(0.11.9), from the drivers' own message definitions (ros-drivers/velodyne branch ros2,
velodyne_msgs; dawonn/vectornav branch ros2, vectornav_msgs). Writes tests/data/ros2/*.cdr
and expected.json (the values put in). Usage: python3 scripts/ros2-vectors.py (with rosbags
installed: pip install rosbags==0.11.9)."""
import struct, json, os
import numpy as np
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

OUT = os.path.join(os.path.dirname(__file__), "..", "tests", "data", "ros2")
ts = get_typestore(Stores.ROS2_HUMBLE)
defs = {
    "velodyne_msgs/msg/VelodynePacket": "builtin_interfaces/Time stamp\nuint8[1206] data\n",
    "velodyne_msgs/msg/VelodyneScan": "std_msgs/Header header\nvelodyne_msgs/VelodynePacket[] packets\n",
    "vectornav_msgs/msg/InsStatus": "uint8 mode\nbool gps_fix\nbool time_error\nbool imu_error\nbool mag_pres_error\nbool gps_error\nbool gps_heading_ins\nbool gps_compass\n",
    "vectornav_msgs/msg/CommonGroup": """std_msgs/Header header
uint16 group_fields
uint64 timestartup
uint64 timegps
uint64 timesyncin
geometry_msgs/Vector3 yawpitchroll
geometry_msgs/Quaternion quaternion
geometry_msgs/Vector3 angularrate
geometry_msgs/Point position
geometry_msgs/Vector3 velocity
geometry_msgs/Vector3 accel
geometry_msgs/Vector3 imu_accel
geometry_msgs/Vector3 imu_rate
geometry_msgs/Vector3 magpres_mag
float32 magpres_temp
float32 magpres_pres
float32 deltatheta_dtime
geometry_msgs/Vector3 deltatheta_dtheta
geometry_msgs/Vector3 deltatheta_dvel
vectornav_msgs/InsStatus insstatus
uint32 syncincnt
uint16 timegpspps
""",
    "vectornav_msgs/msg/TimeUTC": "uint8 year\nuint8 month\nuint8 day\nuint8 hour\nuint8 min\nuint8 sec\nuint16 ms\n",
    "vectornav_msgs/msg/TimeStatus": "bool time_ok\nbool date_ok\nbool utctime_ok\n",
    "vectornav_msgs/msg/TimeGroup": """std_msgs/Header header
uint16 group_fields
uint64 timestartup
uint64 timegps
uint64 gpstow
uint16 gpsweek
uint64 timesyncin
uint64 timegpspps
vectornav_msgs/TimeUTC timeutc
uint32 syncincnt
uint32 syncoutcnt
vectornav_msgs/TimeStatus timestatus
""",
    "vectornav_msgs/msg/VpeStatus": "uint8 attitude_quality\nbool gyro_saturation\nbool gyro_saturation_recovery\nuint8 mag_disturbance\nbool mag_saturation\nuint8 acc_disturbance\nbool acc_saturation\nbool known_mag_disturbance\nbool known_accel_disturbance\n",
    "vectornav_msgs/msg/AttitudeGroup": """std_msgs/Header header
uint16 group_fields
vectornav_msgs/VpeStatus vpestatus
geometry_msgs/Vector3 yawpitchroll
geometry_msgs/Quaternion quaternion
float32[9] dcm
geometry_msgs/Vector3 magned
geometry_msgs/Vector3 accelned
geometry_msgs/Vector3 linearaccelbody
geometry_msgs/Vector3 linearaccelned
geometry_msgs/Vector3 ypru
""",
    "vectornav_msgs/msg/InsGroup": """std_msgs/Header header
uint16 group_fields
vectornav_msgs/InsStatus insstatus
geometry_msgs/Point poslla
geometry_msgs/Point posecef
geometry_msgs/Vector3 velbody
geometry_msgs/Vector3 velned
geometry_msgs/Vector3 velecef
geometry_msgs/Vector3 magecef
geometry_msgs/Vector3 accelecef
geometry_msgs/Vector3 linearaccelecef
float32 posu
float32 velu
""",
}
types = {}
for name, text in defs.items():
    types.update(get_types_from_msg(text, name))
ts.register(types)
T = lambda n: ts.types[n]
Time = T("builtin_interfaces/msg/Time")
Header = T("std_msgs/msg/Header")
V3 = T("geometry_msgs/msg/Vector3")
P3 = T("geometry_msgs/msg/Point")
Q = T("geometry_msgs/msg/Quaternion")
expected = {}

# A scan of three packets, each 1206 bytes of a known pattern.
pk = []
for k in range(3):
    data = np.array([(k * 31 + i * 7) % 256 for i in range(1206)], dtype=np.uint8)
    pk.append(T("velodyne_msgs/msg/VelodynePacket")(stamp=Time(sec=1700000000 + k, nanosec=123456789 + k), data=data))
scan = T("velodyne_msgs/msg/VelodyneScan")(header=Header(stamp=Time(sec=1700000002, nanosec=5), frame_id="velodyne"), packets=pk)
open(os.path.join(OUT, "velodyne_scan.cdr"), "wb").write(ts.serialize_cdr(scan, "velodyne_msgs/msg/VelodyneScan"))
expected["velodyne_scan"] = {"header": [1700000002, 5, "velodyne"], "packets": [[1700000000 + k, 123456789 + k, k * 31 % 256] for k in range(3)]}
empty = T("velodyne_msgs/msg/VelodyneScan")(header=Header(stamp=Time(sec=1, nanosec=2), frame_id=""), packets=[])
open(os.path.join(OUT, "velodyne_scan_empty.cdr"), "wb").write(ts.serialize_cdr(empty, "velodyne_msgs/msg/VelodyneScan"))

status = T("vectornav_msgs/msg/InsStatus")(mode=2, gps_fix=True, time_error=False, imu_error=False, mag_pres_error=False, gps_error=False, gps_heading_ins=True, gps_compass=False)
common = T("vectornav_msgs/msg/CommonGroup")(
    header=Header(stamp=Time(sec=1700000003, nanosec=250000000), frame_id="vectornav"),
    group_fields=0x1000 | 0x0040 | 0x0008 | 0x0002,
    timestartup=123456789012, timegps=1384000000123456789, timesyncin=0,
    yawpitchroll=V3(x=12.5, y=-1.25, z=0.75), quaternion=Q(x=0.0, y=0.0, z=0.0, w=1.0),
    angularrate=V3(x=0.01, y=0.02, z=0.03), position=P3(x=48.38, y=-4.49, z=52.25),
    velocity=V3(x=1.5, y=-0.25, z=0.0), accel=V3(x=0.0, y=0.0, z=-9.8),
    imu_accel=V3(x=0.0, y=0.0, z=0.0), imu_rate=V3(x=0.0, y=0.0, z=0.0), magpres_mag=V3(x=0.0, y=0.0, z=0.0),
    magpres_temp=21.5, magpres_pres=101.3, deltatheta_dtime=0.005,
    deltatheta_dtheta=V3(x=0.0, y=0.0, z=0.0), deltatheta_dvel=V3(x=0.0, y=0.0, z=0.0),
    insstatus=status, syncincnt=42, timegpspps=7)
open(os.path.join(OUT, "common_group.cdr"), "wb").write(ts.serialize_cdr(common, "vectornav_msgs/msg/CommonGroup"))
expected["common_group"] = {"header": [1700000003, 250000000, "vectornav"], "group_fields": 0x104A,
    "timegps": 1384000000123456789, "yawpitchroll": [12.5, -1.25, 0.75], "position": [48.38, -4.49, 52.25],
    "velocity": [1.5, -0.25, 0.0], "mode": 2, "gps_fix": True, "syncincnt": 42, "timegpspps": 7}

ins = T("vectornav_msgs/msg/InsGroup")(
    header=Header(stamp=Time(sec=1700000004, nanosec=0), frame_id="vectornav"), group_fields=0x0200 | 0x0002 | 0x0001,
    insstatus=T("vectornav_msgs/msg/InsStatus")(mode=3, gps_fix=False, time_error=False, imu_error=False, mag_pres_error=False, gps_error=True, gps_heading_ins=False, gps_compass=False),
    poslla=P3(x=48.38, y=-4.49, z=52.25), posecef=P3(x=0.0, y=0.0, z=0.0), velbody=V3(x=0.0, y=0.0, z=0.0),
    velned=V3(x=0.0, y=0.0, z=0.0), velecef=V3(x=0.0, y=0.0, z=0.0), magecef=V3(x=0.0, y=0.0, z=0.0),
    accelecef=V3(x=0.0, y=0.0, z=0.0), linearaccelecef=V3(x=0.0, y=0.0, z=0.0), posu=0.021, velu=0.05)
open(os.path.join(OUT, "ins_group.cdr"), "wb").write(ts.serialize_cdr(ins, "vectornav_msgs/msg/InsGroup"))
expected["ins_group"] = {"group_fields": 0x0203, "mode": 3, "gps_fix": False, "poslla": [48.38, -4.49, 52.25], "posu": 0.021}
tg = T("vectornav_msgs/msg/TimeGroup")(
    header=Header(stamp=Time(sec=1700000005, nanosec=1), frame_id="vectornav"), group_fields=0x0002 | 0x0004 | 0x0008 | 0x0020 | 0x0200,
    timestartup=5, timegps=1384000000123456789, gpstow=345600123456789, gpsweek=2288, timesyncin=0, timegpspps=250000000,
    timeutc=T("vectornav_msgs/msg/TimeUTC")(year=23, month=11, day=14, hour=22, min=13, sec=20, ms=123),
    syncincnt=3, syncoutcnt=4, timestatus=T("vectornav_msgs/msg/TimeStatus")(time_ok=True, date_ok=True, utctime_ok=False))
open(os.path.join(OUT, "time_group.cdr"), "wb").write(ts.serialize_cdr(tg, "vectornav_msgs/msg/TimeGroup"))
expected["time_group"] = {"group_fields": 0x022E, "timegps": 1384000000123456789, "gpstow": 345600123456789, "gpsweek": 2288,
    "timegpspps": 250000000, "timeutc": [23, 11, 14, 22, 13, 20, 123], "timestatus": [True, True, False]}
att = T("vectornav_msgs/msg/AttitudeGroup")(
    header=Header(stamp=Time(sec=1700000006, nanosec=7), frame_id="vectornav"), group_fields=0x0100 | 0x0002,
    vpestatus=T("vectornav_msgs/msg/VpeStatus")(attitude_quality=1, gyro_saturation=False, gyro_saturation_recovery=False,
        mag_disturbance=2, mag_saturation=False, acc_disturbance=0, acc_saturation=True, known_mag_disturbance=False, known_accel_disturbance=True),
    yawpitchroll=V3(x=271.5, y=2.25, z=-3.5), quaternion=Q(x=0.0, y=0.0, z=0.0, w=1.0),
    dcm=np.array([1, 0, 0, 0, 1, 0, 0, 0, 1], dtype=np.float32), magned=V3(x=0.0, y=0.0, z=0.0),
    accelned=V3(x=0.0, y=0.0, z=0.0), linearaccelbody=V3(x=0.0, y=0.0, z=0.0), linearaccelned=V3(x=0.0, y=0.0, z=0.0),
    ypru=V3(x=0.35, y=0.04, z=0.045))
open(os.path.join(OUT, "attitude_group.cdr"), "wb").write(ts.serialize_cdr(att, "vectornav_msgs/msg/AttitudeGroup"))
expected["attitude_group"] = {"group_fields": 0x0102, "yawpitchroll": [271.5, 2.25, -3.5], "ypru": [0.35, 0.04, 0.045]}

# velodyne_pointcloud's XYZIRT clouds (PointcloudXYZIRT: x y z intensity float32, ring uint16,
# time float32): an unorganised little-endian one with a NaN cell, and the same points
# big-endian and organised in 2 rows with 4 bytes of padding per row and float64 time.
PF = T("sensor_msgs/msg/PointField")
pts = [  # x, y, z, intensity, ring, time
    (10.0, 0.0, -2.679492, 7.0, 0, -0.05),        # ring 0 (VLP-16: -15 deg), 10 m ahead
    (0.0, -5.0, 0.0874887, 100.0, 8, -0.0251),     # ring 8 (+1 deg), 5 m to the right
    (float("nan"), float("nan"), float("nan"), 0.0, 3, 0.0),
    (-3.0, 4.0, 1.339746, 255.0, 15, 0.001234),     # ring 15 (+15 deg), behind-left
]
def cloud(big, organised):
    e = ">" if big else "<"
    if organised:
        fields = [PF(name=n, offset=o, datatype=d, count=1) for n, o, d in
                  [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7), ("ring", 16, 4), ("time", 20, 8)]]
        step, fmt = 28, e + "ffffHxxd"
    else:
        fields = [PF(name=n, offset=o, datatype=d, count=1) for n, o, d in
                  [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7), ("ring", 16, 4), ("time", 18, 7)]]
        step, fmt = 22, e + "ffffHf"
    rows = [pts[:2], pts[2:]] if organised else [pts]
    data = b""
    for r in rows:
        data += b"".join(struct.pack(fmt, *p) for p in r) + (b"\xee" * 4 if organised else b"")
    return T("sensor_msgs/msg/PointCloud2")(
        header=Header(stamp=Time(sec=1700000010, nanosec=500000000), frame_id="velodyne"),
        height=len(rows), width=len(rows[0]), fields=fields, is_bigendian=big, point_step=step,
        row_step=step * len(rows[0]) + (4 if organised else 0),
        data=np.frombuffer(data, dtype=np.uint8), is_dense=False)
for name, big, org in [("cloud_xyzirt", False, False), ("cloud_xyzirt_big_organised", True, True)]:
    open(os.path.join(OUT, name + ".cdr"), "wb").write(ts.serialize_cdr(cloud(big, org), "sensor_msgs/msg/PointCloud2"))
expected["cloud_xyzirt"] = {"stamp": [1700000010, 500000000], "points": [list(p) for p in pts]}
json.dump(expected, open(os.path.join(OUT, "expected.json"), "w"), indent=1)
print("written", sorted(os.listdir(OUT)))
