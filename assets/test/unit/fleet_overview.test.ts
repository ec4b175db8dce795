// The operator page's fleet overview: rows from the server's directory (topic `fleet`), and
// what `unreachable` / `reachable` do to the list before the next `vehicles`.
import { describe, expect, it } from "vitest";
import { decodeFleetReply } from "../../src/lib/protocol";
import type { VehicleInfo } from "../../src/lib/protocol";
import { overviewRows, withReachability } from "../../src/operator/fleet";

function fleet(vehicles: unknown[]): readonly VehicleInfo[] {
  const reply = decodeFleetReply({ vehicles });
  if (!reply) throw new Error("bad fleet reply");
  return reply.vehicles;
}

const DIRECTORY = fleet([
  {
    id: "rov1",
    board: "uart",
    node: "rov1@10.0.0.2",
    status: "up",
    helm: "held",
    pilot: "ada",
    link: { up: true, reason: "ok" },
    depth: 12.345,
    heading: Math.PI / 2,
    recording: true,
  },
  {
    id: "rov2",
    board: "simulated",
    node: "rov2@10.0.0.3",
    status: "up",
    helm: "free",
    pilot: null,
    link: { up: false, reason: "no_reply" },
    depth: 0,
    heading: 0,
    recording: false,
  },
  { id: "rov3", board: "simulated", node: "rov3@10.0.0.4", status: "unreachable", helm: null, pilot: null, link: null, depth: null, heading: null, recording: false },
]);

describe("the fleet overview's rows", () => {
  it("shows each vehicle's depth, heading, pilot, link, REC, node and status", () => {
    const [rov1, rov2, rov3] = overviewRows(DIRECTORY, "rov2", "?name=ada");
    expect(rov1).toMatchObject({
      id: "rov1",
      href: "?name=ada&vehicle=rov1",
      current: false,
      node: "rov1@10.0.0.2",
      status: "up",
      depth: "12.35 m",
      heading: "90.0°",
      pilot: "ada",
      link: "up",
      linkUp: true,
      rec: true,
    });
    expect(rov1?.summary).toBe("rov1 on rov1@10.0.0.2: depth 12.35 m, heading 90.0°, pilot ada, link up, recording");
    expect(rov2).toMatchObject({ current: true, depth: "0.00 m", heading: "0.0°", pilot: "nobody", link: "down (no_reply)", linkUp: false, rec: false });
    expect(rov3).toMatchObject({ status: "unreachable", depth: "—", heading: "—", pilot: "—", link: "—", linkUp: null, rec: false });
    expect(rov3?.summary).toBe("rov3 on rov3@10.0.0.4: unreachable");
  });

  it("says unknown (—), not zero or nobody, for what an older server or a fresh vehicle does not say", () => {
    const [solo, fresh] = overviewRows(
      fleet([
        { id: "solo", board: "simulated" },
        { id: "fresh", board: "simulated", node: "n@h", status: "up", helm: "free", pilot: null, link: null, depth: null, heading: null, recording: false },
      ]),
      null,
      "",
    );
    expect(solo).toMatchObject({ node: "—", status: "up", depth: "—", heading: "—", pilot: "—", link: "—", rec: false, href: "?vehicle=solo" });
    expect(fresh).toMatchObject({ depth: "—", heading: "—", pilot: "nobody", link: "—" });
  });

  it("never shows an unreachable vehicle's last readings as live", () => {
    // a server that would still send details with status unreachable
    const [row] = overviewRows(fleet([{ id: "x", board: "uart", status: "unreachable", pilot: "ada", depth: 3, heading: 1, recording: true, link: { up: true } }]), null, "");
    expect(row).toMatchObject({ status: "unreachable", depth: "—", pilot: "—", rec: false });
  });

  it("decodes malformed directory fields as unknown", () => {
    const [v] = fleet([{ id: "x", board: "uart", status: "up", pilot: 7, depth: "deep", heading: Number.NaN, link: { up: "yes" }, recording: "on" }]);
    expect(v?.detail).toEqual({ helm: null, pilot: null, link: null, depth: null, heading: null, recording: false });
  });
});

describe("reachability between two directory updates", () => {
  it("unreachable drops what was known of the vehicle; reachable marks it up again", () => {
    const cut = withReachability(DIRECTORY, "rov1", false);
    expect(cut[0]).toEqual({ id: "rov1", board: "uart", node: "rov1@10.0.0.2", status: "unreachable" });
    expect(cut[1]).toBe(DIRECTORY[1]);
    expect(overviewRows(cut, null, "")[0]).toMatchObject({ status: "unreachable", pilot: "—", rec: false });

    const back = withReachability(cut, "rov1", true);
    expect(back[0]).toMatchObject({ id: "rov1", status: "up" });
    expect(overviewRows(back, null, "")[0]).toMatchObject({ status: "up", depth: "—", pilot: "—" });
  });

  it("an id not listed changes nothing", () => {
    expect(withReachability(DIRECTORY, "ghost", false)).toBe(DIRECTORY);
  });
});
