import { describe, expect, it } from "vitest";
import { INPUT_MODES, NEUTRAL_MANUAL, NEUTRAL_MOTION, manualDemand, motionDemand } from "../../src/input/demand";
import type { InputMode, ThrustDemand } from "../../src/input/demand";
import { routeDemand } from "../../src/operator/routing";
import type { Route, RoutingContext } from "../../src/operator/routing";

const forward = motionDemand(0.5, 0, 0);
const port = manualDemand(0.3, 0, 0);

/** We pilot (epoch 7) a joined vehicle in motion mode with the keyboard, nothing sent yet. */
const piloting: RoutingContext = { selected: "keyboard", controlMode: "motion", sent: null, joined: true, epoch: 7 };

describe("routeDemand: the selected input drives a vehicle we pilot", () => {
  it("sends a new demand with our grant's epoch", () => {
    expect(routeDemand(piloting, "keyboard", forward)).toEqual({ kind: "send", demand: forward, epoch: 7 });
  });

  it("in manual mode, thruster demands", () => {
    expect(routeDemand({ ...piloting, controlMode: "manual", selected: "touch" }, "touch", port)).toEqual({ kind: "send", demand: port, epoch: 7 });
  });

  it("a demand back to neutral is sent like any other (releasing the keys stops the vehicle)", () => {
    expect(routeDemand({ ...piloting, sent: forward }, "keyboard", NEUTRAL_MOTION)).toEqual({ kind: "send", demand: NEUTRAL_MOTION, epoch: 7 });
  });

  it("epoch 0 is an epoch (not 'no helm')", () => {
    expect(routeDemand({ ...piloting, epoch: 0 }, "keyboard", forward)).toEqual({ kind: "send", demand: forward, epoch: 0 });
  });
});

describe("routeDemand: ignored", () => {
  it("another input than the selected one", () => {
    for (const source of INPUT_MODES.filter((m) => m !== "keyboard")) {
      expect(routeDemand(piloting, source, forward)).toEqual({ kind: "ignore", why: "not_selected" });
    }
  });

  it("the headset, even selected (it steers the heading setpoint, never thrust)", () => {
    expect(routeDemand({ ...piloting, selected: "headset" }, "headset", forward)).toEqual({ kind: "ignore", why: "not_selected" });
  });

  it("in DP and in a control mode this page does not know", () => {
    for (const controlMode of ["dp", "auto", ""]) {
      expect(routeDemand({ ...piloting, controlMode }, "keyboard", forward)).toEqual({ kind: "ignore", why: "not_selected" });
    }
  });

  it("the demand sent last, again (compared by value)", () => {
    expect(routeDemand({ ...piloting, sent: motionDemand(0.5, 0, 0) }, "keyboard", forward)).toEqual({ kind: "ignore", why: "unchanged" });
    expect(routeDemand({ ...piloting, sent: NEUTRAL_MANUAL }, "keyboard", manualDemand(0, 0, 0))).toEqual({ kind: "ignore", why: "unchanged" });
  });

  it("not the selected input wins over not connected and not in control: a watcher's other devices say nothing", () => {
    expect(routeDemand({ ...piloting, joined: false, epoch: null }, "gamepad", forward)).toEqual({ kind: "ignore", why: "not_selected" });
  });
});

describe("routeDemand: blocked, and the operator is told why", () => {
  it("no joined channel", () => {
    expect(routeDemand({ ...piloting, joined: false }, "keyboard", forward)).toEqual({ kind: "blocked", why: "not_connected" });
  });

  it("not connected is said before not in control", () => {
    expect(routeDemand({ ...piloting, joined: false, epoch: null }, "keyboard", forward)).toEqual({ kind: "blocked", why: "not_connected" });
  });

  it("joined but without the helm", () => {
    expect(routeDemand({ ...piloting, epoch: null }, "keyboard", forward)).toEqual({ kind: "blocked", why: "not_in_control" });
  });

  it("an unchanged demand is not blocked again (the warning is not repeated for the same keys)", () => {
    expect(routeDemand({ ...piloting, epoch: null, sent: forward }, "keyboard", forward)).toEqual({ kind: "ignore", why: "unchanged" });
  });
});

describe("routeDemand over every combination", () => {
  const controlModes = ["motion", "manual", "dp", "unknown"];
  const demands: ThrustDemand[] = [forward, port, NEUTRAL_MOTION, NEUTRAL_MANUAL];
  const sents: (ThrustDemand | null)[] = [null, forward, NEUTRAL_MANUAL];
  const cases: { ctx: RoutingContext; source: InputMode; demand: ThrustDemand; route: Route }[] = [];
  for (const selected of INPUT_MODES)
    for (const source of INPUT_MODES)
      for (const controlMode of controlModes)
        for (const sent of sents)
          for (const joined of [true, false])
            for (const epoch of [null, 3])
              for (const demand of demands) {
                const ctx = { selected, controlMode, sent, joined, epoch };
                cases.push({ ctx, source, demand, route: routeDemand(ctx, source, demand) });
              }

  it("sends exactly when the selected stick input makes a new demand on a joined vehicle we pilot", () => {
    for (const { ctx, source, demand, route } of cases) {
      const drives = source === ctx.selected && source !== "headset" && (ctx.controlMode === "motion" || ctx.controlMode === "manual");
      const isNew = ctx.sent === null || JSON.stringify(ctx.sent) !== JSON.stringify(demand);
      const sends = drives && isNew && ctx.joined && ctx.epoch !== null;
      expect(route.kind === "send", JSON.stringify({ ctx, source, demand })).toBe(sends);
      if (route.kind === "send") expect(route).toEqual({ kind: "send", demand, epoch: ctx.epoch });
    }
  });

  it("blocks only a new demand of the selected stick input, never one it would ignore", () => {
    for (const { ctx, source, route } of cases) {
      if (route.kind !== "blocked") continue;
      expect(source).toBe(ctx.selected);
      expect(source).not.toBe("headset");
      expect(route.why).toBe(ctx.joined ? "not_in_control" : "not_connected");
    }
  });

  it("the headset never sends", () => {
    expect(cases.filter((c) => c.source === "headset" && c.route.kind !== "ignore")).toEqual([]);
  });

  it("covers every answer", () => {
    const answers = new Set(cases.map(({ route }) => (route.kind === "send" ? "send" : `${route.kind}:${route.why}`)));
    expect([...answers].sort()).toEqual(["blocked:not_connected", "blocked:not_in_control", "ignore:not_selected", "ignore:unchanged", "send"]);
  });
});
