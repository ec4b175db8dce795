/**
 * Which vehicle a watching page opens (the developer and camera pages): `?vehicle=ID` when
 * it is a valid id, else the fleet's first reachable vehicle — asked again every
 * RETRY_MS until the server lists one. What goes wrong is said through `say` ("" when it is
 * over).
 */

import { reasonOf } from "./errors";
import { firstVehicle } from "./first_vehicle";
import type { FleetReply } from "./protocol";

export const VEHICLE_ID = /^[A-Za-z0-9_.-]{1,64}$/;
export const RETRY_MS = 2000;

export async function chooseVehicle(
  client: { fleet(): Promise<FleetReply> },
  requested: string | null,
  say: (message: string) => void,
  sleep: (ms: number) => Promise<void> = (ms) => new Promise((resolve) => setTimeout(resolve, ms)),
): Promise<string | null> {
  if (requested !== null) {
    if (VEHICLE_ID.test(requested)) return requested;
    say(`Invalid vehicle id in the address: "${requested}"`);
    return null;
  }
  for (;;) {
    try {
      const fleet = await client.fleet();
      const first = firstVehicle(fleet.vehicles);
      if (first !== undefined) {
        say("");
        return first.id;
      }
      say("The server has no vehicles.");
    } catch (err) {
      say(`Cannot list vehicles: ${reasonOf(err)}`);
    }
    await sleep(RETRY_MS);
  }
}
