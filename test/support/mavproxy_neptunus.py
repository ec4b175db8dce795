"""A MAVProxy module for the ground station tests (test/e2e/gcs.e2e.mjs): streams MANUAL_CONTROL
at 10 Hz, as a joystick module would (MAVProxy's own joystick module sends RC overrides).

    module load mavproxy_neptunus   (with this directory on PYTHONPATH)
    stick X Y Z R                   stream MANUAL_CONTROL (ArduSub's axes: z 0..1000, 500 neutral)
    stick stop                      stop streaming (the ground station's stick goes silent)

(The command is not called `manual`: MAVProxy's mode module takes a mode's name typed alone,
MANUAL among them, as a mode change.)
"""

import time

from MAVProxy.modules.lib import mp_module


class NeptunusModule(mp_module.MPModule):
    def __init__(self, mpstate):
        super(NeptunusModule, self).__init__(mpstate, "neptunus", "MANUAL_CONTROL stream")
        self.axes = None
        self.last = 0.0
        self.add_command("stick", self.cmd_stick, "stream MANUAL_CONTROL: stick X Y Z R | stick stop")

    def cmd_stick(self, args):
        if args == ["stop"]:
            self.axes = None
            print("stick: stopped")
            return
        if len(args) != 4:
            print("usage: stick X Y Z R | stick stop")
            return
        self.axes = [int(a) for a in args]
        print("stick: streaming %s" % self.axes)

    def idle_task(self):
        if self.axes is None:
            return
        now = time.time()
        if now - self.last >= 0.1:
            self.last = now
            x, y, z, r = self.axes
            self.master.mav.manual_control_send(self.target_system, x, y, z, r, 0)


def init(mpstate):
    return NeptunusModule(mpstate)
