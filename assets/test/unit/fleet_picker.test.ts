// The operator page's vehicle picker: the fleet's vehicles as the server lists them (with their
// node), their labels and the deep links they open.
import { describe, expect, it } from "vitest";
import { decodeFleetReply } from "../../src/lib/protocol";
import { vehicleHref, vehicleLabel } from "../../src/operator/format";

describe("the fleet's vehicles", () => {
  it("decodes each vehicle's node and status when the server says them", () => {
    expect(
      decodeFleetReply({
        vehicles: [
          { id: "rov1", board: "uart", node: "rov1@10.0.0.2", status: "up", helm: "free", pilot: null },
          { id: "rov2", board: "simulated", node: "rov2@10.0.0.3", status: "unreachable" },
          { id: "solo", board: "simulated" },
        ],
      }),
    ).toEqual({
      vehicles: [
        {
          id: "rov1",
          board: "uart",
          node: "rov1@10.0.0.2",
          status: "up",
          detail: { helm: "free", pilot: null, link: null, depth: null, heading: null, recording: false },
        },
        { id: "rov2", board: "simulated", node: "rov2@10.0.0.3", status: "unreachable" },
        { id: "solo", board: "simulated" },
      ],
    });
    expect(decodeFleetReply({ vehicles: [{ id: "x", board: "simulated", node: 7 }] })).toEqual({
      vehicles: [{ id: "x", board: "simulated" }],
    });
  });

  it("labels a vehicle with its node, and says when it is unreachable", () => {
    expect(vehicleLabel({ id: "rov1", board: "uart", node: "rov1@10.0.0.2", status: "up" })).toBe("rov1 on rov1@10.0.0.2");
    expect(vehicleLabel({ id: "rov2", board: "uart", node: "rov2@10.0.0.3", status: "unreachable" })).toBe(
      "rov2 on rov2@10.0.0.3 (unreachable)",
    );
    expect(vehicleLabel({ id: "solo", board: "simulated" })).toBe("solo");
  });

  it("links to ?vehicle=ID, keeping the page's other parameters", () => {
    expect(vehicleHref("", "rov 2")).toBe("?vehicle=rov+2");
    expect(vehicleHref("?vehicle=rov1&debug=1", "rov2")).toBe("?vehicle=rov2&debug=1");
  });
});
