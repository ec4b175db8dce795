import { describe, expect, it } from "vitest";
import { RETRY_MS, chooseVehicle } from "../../src/lib/choose_vehicle";
import type { FleetReply, VehicleInfo } from "../../src/lib/protocol";

const vehicle = (id: string, status: VehicleInfo["status"] = "up"): VehicleInfo => ({ id, board: "simulated", node: "a@h", status }) as VehicleInfo;

describe("the vehicle a watching page opens", () => {
  it("is the address's, when it is a valid id", async () => {
    const said: string[] = [];
    const never = { fleet: (): Promise<FleetReply> => Promise.reject(new Error("not asked")) };
    expect(await chooseVehicle(never, "rov-2", (m) => said.push(m))).toBe("rov-2");
    expect(await chooseVehicle(never, "../etc", (m) => said.push(m))).toBeNull();
    expect(said).toEqual(['Invalid vehicle id in the address: "../etc"']);
  });

  it("else the fleet's first reachable one, asking again until there is one", async () => {
    const replies: (FleetReply | Error)[] = [new Error("timeout"), { vehicles: [] } as unknown as FleetReply, { vehicles: [vehicle("far", "unreachable"), vehicle("near")] } as unknown as FleetReply];
    const said: string[] = [];
    const slept: number[] = [];
    const client = {
      fleet: (): Promise<FleetReply> => {
        const r = replies.shift();
        return r instanceof Error ? Promise.reject(r) : Promise.resolve(r as FleetReply);
      },
    };
    const id = await chooseVehicle(client, null, (m) => said.push(m), async (ms) => {
      slept.push(ms);
    });
    expect(id).toBe("near");
    expect(said).toEqual(["Cannot list vehicles: timeout", "The server has no vehicles.", ""]);
    expect(slept).toEqual([RETRY_MS, RETRY_MS]);
  });
});
