"""A fake ArduSub vehicle for the `mavlink` board's tests, written with pymavlink.

Run with the project's virtualenv (`make setup`):

  .venv/bin/python test/support/fake_ardusub.py [--udp PORT] [--tcp PORT] [--frame N]

It listens on UDP (default: an ephemeral port on 127.0.0.1; it answers whoever sent the last
datagram, as ArduSub's UDP server does) or, with --tcp, accepts one TCP connection at a time
(as ArduPilot SITL on tcp:5760). It behaves as ArduSub does toward a ground station:

* HEARTBEAT at 1 Hz from system 1 / component 1: MAV_TYPE_SUBMARINE, MAV_AUTOPILOT_ARDUPILOTMEGA,
  custom_mode the Sub mode number (boots in MANUAL, 19), armed in base_mode bit 128.
* Telemetry without any request, at ArduSub's default stream rates: ATTITUDE and VFR_HUD 10 Hz,
  GLOBAL_POSITION_INT 3 Hz, SYS_STATUS, SCALED_PRESSURE and SERVO_OUTPUT_RAW 2 Hz; TIMESYNC
  requests (tc1 = 0) are answered. REQUEST_DATA_STREAM sets the rate of its stream.
* A position only when told one (as ArduSub's EKF has one only with a DVL or a GPS):
  LOCAL_POSITION_NED at 3 Hz in the POSITION stream with GLOBAL_POSITION_INT, moved by the
  toy motion (0.5 m/s at full forward or lateral, by the heading); GLOBAL_POSITION_INT's
  latitude and longitude are 0, 0 (no origin, as ArduSub sends them without a GPS) unless told
  an origin: then the origin plus the position.
* COMMAND_LONG MAV_CMD_COMPONENT_ARM_DISARM (400): arming answers COMMAND_ACK ACCEPTED, or —
  when told to refuse — STATUSTEXT (severity CRITICAL) with ArduSub's text, then ACK FAILED;
  disarming a disarmed vehicle answers FAILED. MAV_CMD_DO_SET_MODE (176) with a known Sub
  mode answers ACCEPTED (else DENIED); other commands UNSUPPORTED.
* MANUAL_CONTROL only from system 255 with target 1 (others ignored, as ArduSub does), acted on
  only while armed: x/y/z/r (z 500 neutral) drive the vectored frame's six motors scaled by the
  joystick gain (JS_GAIN_DEFAULT 0.5 unless told otherwise; SERVO_OUTPUT_RAW, neutral 1500,
  ±400 µs at gain 1) and a toy motion (depth, heading). The gain is reported as
  NAMED_VALUE_FLOAT `PilotGain` with SYS_STATUS (the EXTENDED_STATUS stream), as ArduSub does.
* PARAM_REQUEST_READ of `FRAME_CONFIG` (by name, or by its index 7) answers PARAM_VALUE with
  the frame (`--frame N`, default 1: vectored; ArduSub's FRAME_CONFIG values), as an INT8
  parameter; other parameters are not answered (as ArduSub ignores a name it does not have).
  A frame without lateral thrust (SimpleROV-3 and -4, FRAME_CONFIG 4 and 5) ignores `y`.
* Failsafes: 3 s without pilot input (MANUAL_CONTROL) while armed → STATUSTEXT "Lost manual
  control", neutral, disarm (FS_PILOT_INPUT=2); once it has heard system 255, 5 s without its
  HEARTBEAT → "MYGCS: 255, heartbeat lost", disarm (FS_GCS_ENABLE=2).

What it receives and does is reported on stdout as JSON lines (`{"event": ...}`): `listening`
(with `port`), `manual_control` (x y z r buttons, sysid, target, armed), `command` (command,
params, result), `heartbeat` (the GCS's), `armed` (true/false, why), `failsafe` (what),
`request_data_stream`, `mode`, `gain`, `param_request_read` (param_id, param_index,
answered). Lines on stdin are JSON commands: `{"refuse_arm": TEXT}`
(or null to accept again), `{"gain": G}` (the joystick gain, as ArduSub's gain buttons set it),
`{"frame": N}` (FRAME_CONFIG from now on), `{"answer_params": false}` (PARAM_REQUEST_READ
unanswered until `true` again), `{"position": {"north": N, "east": E}}` (m; null: no position again), `{"origin": {"lat": DEG,
"lon": DEG}}` (its EKF origin), `{"quit": true}`.
"""

import argparse
import json
import math
import os
import select
import socket
import sys
import time

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

SUB_MODES = {0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 3: "AUTO", 4: "GUIDED", 7: "CIRCLE",
             9: "SURFACE", 16: "POSHOLD", 19: "MANUAL", 20: "MOTOR_DETECT", 21: "SURFTRAK"}
GCS_SYSID = 255
PILOT_TIMEOUT = 3.0
GCS_TIMEOUT = 5.0
JS_GAIN_DEFAULT = 0.5
# vectored frame: (yaw, throttle, forward, lateral) factors of motors 1..6
FACTORS = [(1, 0, -1, 1), (-1, 0, -1, -1), (-1, 0, 1, 1), (1, 0, 1, -1), (0, -1, 0, 0),
           (0, -1, 0, 0)]
# MAV_DATA_STREAM id -> (message kinds, default Hz) as ArduSub streams them
STREAMS = {1: (["scaled_pressure"], 2), 2: (["sys_status"], 2), 3: (["servo_output_raw"], 2),
           6: (["global_position_int", "local_position_ned"], 3), 10: (["attitude"], 10),
           11: (["vfr_hud"], 10)}

# ArduSub's FRAME_CONFIG: the frames without lateral thrust (SimpleROV-3, SimpleROV-4)
NO_LATERAL_FRAMES = (4, 5)
FRAME_CONFIG_INDEX = 7
MAV_PARAM_TYPE_INT8 = 2
PARAM_COUNT = 1391

PREARM_NO_DISARM_BUTTON = "PreArm: Must assign a disarm or arm_toggle button or disarm aux function"


def report(event, **fields):
    fields["event"] = event
    try:
        sys.stdout.write(json.dumps(fields) + "\n")
        sys.stdout.flush()
    except BrokenPipeError:
        # the test closed our port: nobody is listening any more
        os._exit(0)


class Link:
    """UDP (answer the last sender) or TCP (one connection at a time)."""

    def __init__(self, udp_port, tcp_port):
        self.peer = None
        self.conn = None
        if tcp_port is not None:
            self.kind = "tcp"
            self.server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self.server.bind(("127.0.0.1", tcp_port))
            self.server.listen(1)
            self.port = self.server.getsockname()[1]
        else:
            self.kind = "udp"
            self.server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.server.bind(("127.0.0.1", udp_port or 0))
            self.port = self.server.getsockname()[1]

    def readers(self):
        return [self.server] + ([self.conn] if self.conn else [])

    def read(self, sock):
        if self.kind == "udp":
            data, self.peer = self.server.recvfrom(65536)
            return data
        if sock is self.server:
            if self.conn:
                self.conn.close()
            self.conn, _ = self.server.accept()
            self.conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            report("connected")
            return b""
        data = self.conn.recv(65536)
        if not data:
            self.conn.close()
            self.conn = None
            report("disconnected")
        return data

    def write(self, data):
        try:
            if self.kind == "udp" and self.peer:
                self.server.sendto(data, self.peer)
            elif self.kind == "tcp" and self.conn:
                self.conn.sendall(data)
        except OSError:
            pass


class FakeSub:
    def __init__(self, link, frame=1):
        self.link = link
        self.frame = frame
        self.answer_params = True
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.start = time.monotonic()
        self.armed = False
        self.mode = 19
        self.refuse_arm = None
        self.gain = JS_GAIN_DEFAULT
        self.control = {"x": 0, "y": 0, "z": 500, "r": 0}
        self.pilot_at = None
        self.pilot_failsafe = False
        self.gcs_at = None
        self.depth = 0.0
        self.heading = 0.0
        self.last_step = self.start
        self.position = None
        self.origin = None
        self.rates = {kind: hz for kinds, hz in STREAMS.values() for kind in kinds}
        self.rates["heartbeat"] = 1
        self.next_at = {kind: self.start for kind in self.rates}

    def now_ms(self):
        return int((time.monotonic() - self.start) * 1000)

    def send(self, msg):
        self.link.write(msg.pack(self.mav))
        self.mav.seq = (self.mav.seq + 1) % 256

    def text(self, severity, text):
        """STATUSTEXT as ArduPilot sends it: a text over 50 bytes in chunks of one id."""
        data = text.encode()
        if len(data) <= 50:
            self.send(mavlink.MAVLink_statustext_message(severity, data))
            return
        self.text_id = getattr(self, "text_id", 0) % 65535 + 1
        chunks = [data[i:i + 50] for i in range(0, len(data), 50)]
        if len(chunks[-1]) == 50:
            chunks.append(b"")
        for seq, chunk in enumerate(chunks):
            self.send(mavlink.MAVLink_statustext_message(severity, chunk, self.text_id, seq))

    # --- what the ground station sends ---------------------------------------------------

    def handle(self, msg):
        kind = msg.get_type()
        src = msg.get_srcSystem()
        if kind == "HEARTBEAT" and src == GCS_SYSID:
            self.gcs_at = time.monotonic()
            report("heartbeat", sysid=src, compid=msg.get_srcComponent(), type=msg.type)
        elif kind == "MANUAL_CONTROL":
            accepted = src == GCS_SYSID and msg.target == 1
            report("manual_control", x=msg.x, y=msg.y, z=msg.z, r=msg.r, buttons=msg.buttons,
                   sysid=src, target=msg.target, armed=self.armed, accepted=accepted)
            if accepted:
                self.control = {"x": msg.x, "y": msg.y, "z": msg.z, "r": msg.r}
                self.pilot_at = time.monotonic()
                self.pilot_failsafe = False
                self.gcs_at = time.monotonic()
        elif kind == "COMMAND_LONG":
            self.command(msg)
        elif kind == "REQUEST_DATA_STREAM":
            report("request_data_stream", stream=msg.req_stream_id, rate=msg.req_message_rate,
                   start=msg.start_stop)
            if msg.req_stream_id in STREAMS:
                for k in STREAMS[msg.req_stream_id][0]:
                    self.rates[k] = msg.req_message_rate if msg.start_stop else 0
        elif kind == "PARAM_REQUEST_READ":
            frame = msg.param_id == "FRAME_CONFIG" or (msg.param_id == "" and
                                                       msg.param_index == FRAME_CONFIG_INDEX)
            answered = frame and self.answer_params
            report("param_request_read", param_id=msg.param_id, param_index=msg.param_index,
                   answered=answered, sysid=src)
            if answered:
                self.send(mavlink.MAVLink_param_value_message(
                    b"FRAME_CONFIG", float(self.frame), MAV_PARAM_TYPE_INT8, PARAM_COUNT,
                    FRAME_CONFIG_INDEX))
        elif kind == "TIMESYNC" and msg.tc1 == 0:
            self.send(mavlink.MAVLink_timesync_message(time.monotonic_ns(), msg.ts1))

    def command(self, msg):
        params = [msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6,
                  msg.param7]
        result = mavlink.MAV_RESULT_UNSUPPORTED
        if msg.command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            if msg.param1 == 1:
                if self.armed:
                    result = mavlink.MAV_RESULT_ACCEPTED
                elif self.refuse_arm:
                    self.text(mavlink.MAV_SEVERITY_CRITICAL, self.refuse_arm)
                    result = mavlink.MAV_RESULT_FAILED
                else:
                    self.set_armed(True, "gcs")
                    result = mavlink.MAV_RESULT_ACCEPTED
            else:
                if self.armed:
                    self.set_armed(False, "gcs")
                    result = mavlink.MAV_RESULT_ACCEPTED
                else:
                    result = mavlink.MAV_RESULT_FAILED
        elif msg.command == mavlink.MAV_CMD_DO_SET_MODE:
            mode = int(msg.param2)
            if mode in SUB_MODES and int(msg.param1) & 1:
                self.mode = mode
                report("mode", mode=SUB_MODES[mode])
                result = mavlink.MAV_RESULT_ACCEPTED
            else:
                result = mavlink.MAV_RESULT_DENIED
        elif msg.command in (mavlink.MAV_CMD_DO_SET_SERVO, mavlink.MAV_CMD_DO_MOUNT_CONTROL):
            result = mavlink.MAV_RESULT_ACCEPTED
        report("command", command=msg.command, params=params, result=result,
               sysid=msg.get_srcSystem())
        self.send(mavlink.MAVLink_command_ack_message(msg.command, result))

    def set_armed(self, armed, why):
        self.armed = armed
        if armed:
            self.pilot_at = time.monotonic()
            self.pilot_failsafe = False
        else:
            self.control = {"x": 0, "y": 0, "z": 500, "r": 0}
        self.text(mavlink.MAV_SEVERITY_INFO, "Armed" if armed else "Disarmed")
        report("armed", armed=armed, why=why)
        self.heartbeat()

    # --- what it does on its own ---------------------------------------------------------

    def failsafes(self, now):
        if self.armed and not self.pilot_failsafe and self.pilot_at and \
                now - self.pilot_at > PILOT_TIMEOUT:
            self.pilot_failsafe = True
            self.text(mavlink.MAV_SEVERITY_CRITICAL, "Lost manual control")
            report("failsafe", what="pilot_input")
            self.set_armed(False, "pilot_input_failsafe")
        if self.armed and self.gcs_at and now - self.gcs_at > GCS_TIMEOUT:
            self.text(mavlink.MAV_SEVERITY_CRITICAL, "MYGCS: 255, heartbeat lost")
            report("failsafe", what="gcs")
            self.gcs_at = None
            self.set_armed(False, "gcs_failsafe")

    def motors(self):
        c = self.control if self.armed else {"x": 0, "y": 0, "z": 500, "r": 0}
        # RC override expiry (RC_OVERRIDE_TIME 3 s): outputs back to neutral
        if self.pilot_at is None or time.monotonic() - self.pilot_at > 3.0:
            c = {"x": 0, "y": 0, "z": 500, "r": 0}
        throttle = (c["z"] - 500) * 2
        outs = []
        lateral = 0 if self.frame in NO_LATERAL_FRAMES else c["y"]
        for yaw, thr, fwd, lat in FACTORS:
            v = yaw * c["r"] + thr * throttle + fwd * c["x"] + lat * lateral
            outs.append(int(max(1100, min(1900, 1500 + 400 * self.gain * v / 1000))))
        return outs, c

    def step(self, now):
        dt = now - self.last_step
        self.last_step = now
        _, c = self.motors()
        # toy motion: 0.5 m/s at full heave, 0.5 rad/s at full yaw
        self.depth = max(0.0, self.depth - 0.5 * self.gain * (c["z"] - 500) / 500 * dt)
        self.heading = (self.heading + 0.5 * self.gain * c["r"] / 1000 * dt) % (2 * math.pi)
        if self.position is not None:
            forward = 0.5 * self.gain * c["x"] / 1000
            lateral = 0.0 if self.frame in NO_LATERAL_FRAMES else 0.5 * self.gain * c["y"] / 1000
            cos, sin = math.cos(self.heading), math.sin(self.heading)
            self.position = (self.position[0] + (forward * cos - lateral * sin) * dt,
                             self.position[1] + (forward * sin + lateral * cos) * dt)

    def heartbeat(self):
        base = 1 | 16 | 64 | (128 if self.armed else 0)
        status = mavlink.MAV_STATE_ACTIVE if self.armed else mavlink.MAV_STATE_STANDBY
        self.send(mavlink.MAVLink_heartbeat_message(
            mavlink.MAV_TYPE_SUBMARINE, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, base, self.mode,
            status, 3))

    def emit(self, kind):
        t = self.now_ms()
        yaw = self.heading if self.heading <= math.pi else self.heading - 2 * math.pi
        if kind == "heartbeat":
            self.heartbeat()
        elif kind == "attitude":
            self.send(mavlink.MAVLink_attitude_message(t, 0.01, -0.02, yaw, 0, 0, 0))
        elif kind == "vfr_hud":
            self.send(mavlink.MAVLink_vfr_hud_message(0, 0, int(math.degrees(self.heading)), 0,
                                                      -self.depth, 0))
        elif kind == "global_position_int":
            lat, lon = 0, 0
            if self.origin is not None and self.position is not None:
                # a local tangent plane, as ArduPilot offsets its locations
                north, east = self.position
                lat0 = math.radians(self.origin[0])
                lat = round((self.origin[0] + math.degrees(north / 6378137.0)) * 1e7)
                lon = round((self.origin[1] + math.degrees(east / (6378137.0 * math.cos(lat0))))
                            * 1e7)
            self.send(mavlink.MAVLink_global_position_int_message(
                t, lat, lon, int(-self.depth * 1000), int(-self.depth * 1000), 0, 0, 0,
                int(math.degrees(self.heading) * 100)))
        elif kind == "local_position_ned" and self.position is not None:
            self.send(mavlink.MAVLink_local_position_ned_message(
                t, self.position[0], self.position[1], self.depth, 0, 0, 0))
        elif kind == "sys_status":
            self.send(mavlink.MAVLink_sys_status_message(0, 0, 0, 200, 15800, 150, 80, 0, 0, 0, 0,
                                                         0, 0))
            self.send(mavlink.MAVLink_named_value_float_message(t, b"PilotGain", self.gain))
        elif kind == "scaled_pressure":
            self.send(mavlink.MAVLink_scaled_pressure_message(
                t, 1030.0 + 98.1 * self.depth, 0.0, 1500))
        elif kind == "servo_output_raw":
            outs, _ = self.motors()
            servos = outs + [1500, 1500] + [0] * 8
            self.send(mavlink.MAVLink_servo_output_raw_message(t * 1000, 0, *servos))

    def tick(self, now):
        self.failsafes(now)
        self.step(now)
        for kind, hz in self.rates.items():
            if hz > 0 and now >= self.next_at[kind]:
                self.next_at[kind] = max(self.next_at[kind] + 1.0 / hz, now)
                self.emit(kind)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--udp", type=int, default=0)
    parser.add_argument("--tcp", type=int, default=None)
    parser.add_argument("--frame", type=int, default=1)
    args = parser.parse_args()
    link = Link(args.udp, args.tcp)
    sub = FakeSub(link, args.frame)
    report("listening", port=link.port, kind=link.kind)
    stdin = sys.stdin.buffer
    pending = b""
    while True:
        ready, _, _ = select.select(link.readers() + [stdin], [], [], 0.01)
        for sock in ready:
            if sock is stdin:
                chunk = os.read(stdin.fileno(), 4096)
                if not chunk:
                    return
                pending += chunk
                while b"\n" in pending:
                    line, pending = pending.split(b"\n", 1)
                    if line.strip():
                        order = json.loads(line)
                        if order.get("quit"):
                            return
                        if "refuse_arm" in order:
                            sub.refuse_arm = order["refuse_arm"]
                            report("refuse_arm", text=sub.refuse_arm)
                        if "position" in order:
                            p = order["position"]
                            sub.position = None if p is None else (float(p["north"]),
                                                                   float(p["east"]))
                            report("position", position=p)
                        if "origin" in order:
                            sub.origin = (float(order["origin"]["lat"]),
                                          float(order["origin"]["lon"]))
                            report("origin", origin=order["origin"])
                        if "frame" in order:
                            sub.frame = int(order["frame"])
                            report("frame", frame=sub.frame)
                        if "answer_params" in order:
                            sub.answer_params = bool(order["answer_params"])
                            report("answer_params", answer=sub.answer_params)
                        if "gain" in order:
                            sub.gain = max(0.1, min(1.0, float(order["gain"])))
                            report("gain", gain=sub.gain)
            else:
                data = link.read(sock)
                if data:
                    try:
                        msgs = sub.mav.parse_buffer(data) or []
                    except mavlink.MAVError:
                        msgs = []
                    for msg in msgs:
                        if msg.get_type() != "BAD_DATA":
                            sub.handle(msg)
        sub.tick(time.monotonic())


if __name__ == "__main__":
    main()
