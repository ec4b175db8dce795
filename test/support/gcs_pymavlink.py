"""A ground station written with pymavlink, for the ground station tests
(test/neptunus_web/gcs_external_test.exs). Run with the project's virtualenv:

  .venv/bin/python test/support/gcs_pymavlink.py watch PORT SECONDS [PASSPHRASE]
      connects (heartbeats at 1 Hz, signed when given a passphrase, as MAVProxy's
      `signing key` does) and reports what it heard for SECONDS
  .venv/bin/python test/support/gcs_pymavlink.py fly PORT SYSID
      the whole tour of a vehicle: telemetry, a message interval, AUTOPILOT_VERSION, the
      parameters (a set refused while it does not pilot), a stick that moves nothing without
      the helm, the helm, arm, MANUAL_CONTROL at 10 Hz for 2 s, silence, disarm

  .venv/bin/python test/support/gcs_pymavlink.py stick PORT SYSID X Y
      the helm, then MANUAL_CONTROL x = X, y = Y (lateral), z neutral at 10 Hz for 2 s

  .venv/bin/python test/support/gcs_pymavlink.py position PORT SYSID
      waits up to 60 s for LOCAL_POSITION_NED; then at 5 Hz (SET_MESSAGE_INTERVAL, read back
      with GET_MESSAGE_INTERVAL) for 2 s; then off for 1.5 s; then once by REQUEST_MESSAGE;
      and counts GLOBAL_POSITION_INT throughout

  .venv/bin/python test/support/gcs_pymavlink.py behind PORT SYSID SECONDS
      an unsigned ground station behind a signing MAVProxy (`--out=udpout:127.0.0.1:PORT`):
      listens on PORT (udpin), and once it hears the vehicle asks for its parameters

PORT is `N` (udpout to 127.0.0.1:N: the endpoint is udpin) or `tcp:N` (a connection to a
tcpin endpoint).

Every answer is one JSON document on stdout.
"""

import hashlib
import json
import os
import sys
import time

os.environ.setdefault("MAVLINK20", "1")

from pymavlink import mavutil  # noqa: E402


def connect(port, passphrase=None):
    device = "tcp:127.0.0.1:%s" % port[4:] if port.startswith("tcp:") else "udpout:127.0.0.1:%s" % port
    m = mavutil.mavlink_connection(device, source_system=255, source_component=190)
    if passphrase:
        key = hashlib.sha256(passphrase.encode("ascii")).digest()
        m.setup_signing(key, sign_outgoing=True)
    return m


def heartbeat(m):
    m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)


def watch(port, seconds, passphrase=None):
    m = connect(port, passphrase)
    counts = {}
    systems = set()
    listen(m, None, seconds, counts, systems=systems)
    signing = m.mav.signing
    return {
        "messages": counts,
        "systems": sorted(systems),
        "goodsig": signing.goodsig_count if passphrase else None,
        "badsig": signing.badsig_count if passphrase else None,
    }


def wait(m, kind, condition=lambda msg: True, timeout=5.0):
    deadline = time.time() + timeout
    while time.time() < deadline:
        msg = m.recv_match(type=kind, blocking=True, timeout=0.2)
        if msg is not None and condition(msg):
            return msg
    return None


def command(m, sysid, cmd, *params):
    params = list(params) + [0.0] * (7 - len(params))
    m.mav.command_long_send(sysid, 1, cmd, 0, *params)
    ack = wait(m, "COMMAND_ACK", lambda a: a.command == cmd)
    return None if ack is None else ack.result


def fly(port, sysid):
    m = connect(port)
    heartbeat(m)
    report = {}
    hb = wait(m, "HEARTBEAT", lambda h: h.get_srcSystem() == sysid)
    report["heartbeat"] = None if hb is None else {"type": hb.type, "autopilot": hb.autopilot, "base_mode": hb.base_mode, "custom_mode": hb.custom_mode}

    # telemetry at the default rates: each message seen in 3 s
    seen = {}
    deadline = time.time() + 3
    while time.time() < deadline:
        msg = m.recv_match(blocking=True, timeout=0.2)
        if msg is not None and msg.get_srcSystem() == sysid:
            seen[msg.get_type()] = seen.get(msg.get_type(), 0) + 1
    report["seen"] = seen

    report["interval_ack"] = command(m, sysid, 511, 30, 200000)
    report["autopilot_version_ack"] = command(m, sysid, 512, 148)
    av = wait(m, "AUTOPILOT_VERSION")
    report["capabilities"] = None if av is None else av.capabilities

    m.mav.param_request_list_send(sysid, 1)
    names = {}
    deadline = time.time() + 5
    while time.time() < deadline:
        p = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.2)
        if p is not None:
            names[p.param_id] = p.param_value
            if len(names) == p.param_count:
                break
    report["params"] = names

    # a set it may not make (LIGHTS is the pilot's): the answer is the value it keeps
    m.mav.param_set_send(sysid, 1, b"LIGHTS", 40.0, mavutil.mavlink.MAV_PARAM_TYPE_REAL32)
    kept = wait(m, "PARAM_VALUE", lambda p: p.param_id == "LIGHTS")
    report["lights_refused"] = None if kept is None else kept.param_value

    # the stick without the helm moves nothing
    report["servo_without_helm"] = stick(m, sysid, 15)

    report["helm_ack"] = command(m, sysid, 32100, 0, 1, 0, 10)
    report["arm_ack"] = command(m, sysid, 400, 1)
    armed = wait(m, "HEARTBEAT", lambda h: h.get_srcSystem() == sysid and h.base_mode & 128)
    report["armed_heartbeat"] = armed is not None
    # the stick at 10 Hz for 2 s (forward, down), then silence
    outputs = stick(m, sysid, 20)
    report["servo"] = outputs[-1] if outputs else None
    stop = wait(m, "STATUSTEXT", lambda t: "stopped: deadman" in t.text, timeout=3)
    report["deadman_text"] = None if stop is None else stop.text
    heartbeat(m)
    report["disarm_ack"] = command(m, sysid, 400, 0)
    disarmed = wait(m, "HEARTBEAT", lambda h: h.get_srcSystem() == sysid and not h.base_mode & 128)
    report["disarmed_heartbeat"] = disarmed is not None
    return report


def sticks(port, sysid, x, y):
    m = connect(port)
    heartbeat(m)
    hb = wait(m, "HEARTBEAT", lambda h: h.get_srcSystem() == sysid)
    report = {"heartbeat": hb is not None}
    report["helm_ack"] = command(m, sysid, 32100, 0, 1, 0, 10)
    for i in range(20):
        m.mav.manual_control_send(sysid, x, y, 500, 0, 0)
        if i % 10 == 0:
            heartbeat(m)
        until = time.time() + 0.1
        while time.time() < until:
            m.recv_match(blocking=True, timeout=max(0.0, until - time.time()))
    return report


def listen(m, sysid, seconds, counts, until=lambda msg: False, systems=None):
    """Every message from SYSID (None: from anyone) for SECONDS (a heartbeat a second keeps
    the session), counted by type in COUNTS, the systems heard in SYSTEMS; the
    LOCAL_POSITION_NEDs as dicts; stops early at the first message for which UNTIL is true."""
    positions = []
    deadline = time.time() + seconds
    last_hb = 0
    while time.time() < deadline:
        if time.time() - last_hb >= 1:
            heartbeat(m)
            last_hb = time.time()
        msg = m.recv_match(blocking=True, timeout=0.2)
        if msg is None or msg.get_type() == "BAD_DATA":
            continue
        if sysid is not None and msg.get_srcSystem() != sysid:
            continue
        if systems is not None and msg.get_type() == "HEARTBEAT":
            systems.add(msg.get_srcSystem())
        counts[msg.get_type()] = counts.get(msg.get_type(), 0) + 1
        if msg.get_type() == "LOCAL_POSITION_NED":
            positions.append(msg.to_dict())
        if until(msg):
            break
    return positions


def position(port, sysid):
    m = connect(port)
    counts = {}
    is_position = lambda msg: msg.get_type() == "LOCAL_POSITION_NED"
    report = {"first": listen(m, sysid, 60, counts, is_position)}
    report["interval_ack"] = command(m, sysid, 511, 32, 200000)
    m.mav.command_long_send(sysid, 1, 510, 0, 32, 0, 0, 0, 0, 0, 0)
    got = wait(m, "MESSAGE_INTERVAL", lambda i: i.message_id == 32)
    report["interval_us"] = None if got is None else got.interval_us
    report["at_5hz"] = listen(m, sysid, 2, counts)
    # off: the session changed its schedule before it acknowledged, and the frames it sends
    # after the ACK follow it on the same socket
    report["off_ack"] = command(m, sysid, 511, 32, -1)
    report["while_off"] = listen(m, sysid, 1.5, counts)
    report["request_ack"] = command(m, sysid, 512, 32)
    report["requested"] = listen(m, sysid, 3, counts, is_position)
    report["global_position_int"] = counts.get("GLOBAL_POSITION_INT", 0)
    return report


def behind(port, sysid, seconds):
    m = mavutil.mavlink_connection("udpin:127.0.0.1:%d" % port, source_system=255, source_component=190)
    report = {"heartbeat": None, "params": 0}
    names = set()
    deadline = time.time() + seconds
    last_hb = 0
    while time.time() < deadline:
        if report["heartbeat"] is not None and time.time() - last_hb >= 1:
            heartbeat(m)
            last_hb = time.time()
        msg = m.recv_match(blocking=True, timeout=0.2)
        if msg is None or msg.get_srcSystem() != sysid:
            continue
        if msg.get_type() == "HEARTBEAT" and report["heartbeat"] is None:
            report["heartbeat"] = {"type": msg.type, "autopilot": msg.autopilot}
            heartbeat(m)
            m.mav.param_request_list_send(sysid, 1)
        elif msg.get_type() == "PARAM_VALUE":
            names.add(msg.param_id)
            if len(names) == msg.param_count:
                report["params"] = len(names)
                break
    return report


def stick(m, sysid, n):
    """MANUAL_CONTROL at 10 Hz, n times (forward, down), with a heartbeat each second; the
    SERVO_OUTPUT_RAWs heard meanwhile, as their first three outputs (go()'s port, vertical,
    starboard)."""
    outputs = []
    for i in range(n):
        m.mav.manual_control_send(sysid, 600, 0, 250, 0, 0)
        if i % 10 == 0:
            heartbeat(m)
        until = time.time() + 0.1
        while time.time() < until:
            msg = m.recv_match(type="SERVO_OUTPUT_RAW", blocking=True, timeout=max(0.0, until - time.time()))
            if msg is not None:
                outputs.append([msg.servo1_raw, msg.servo2_raw, msg.servo3_raw])
    return outputs


def main(argv):
    command_name = argv[1] if len(argv) > 1 else ""
    if command_name == "watch":
        answer = watch(argv[2], float(argv[3]), argv[4] if len(argv) > 4 else None)
    elif command_name == "behind":
        answer = behind(int(argv[2]), int(argv[3]), float(argv[4]))
    elif command_name == "stick":
        answer = sticks(argv[2], int(argv[3]), int(argv[4]), int(argv[5]))
    elif command_name == "position":
        answer = position(argv[2], int(argv[3]))
    elif command_name == "fly":
        answer = fly(argv[2], int(argv[3]))
    else:
        sys.stderr.write(__doc__)
        return 2
    json.dump(answer, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
