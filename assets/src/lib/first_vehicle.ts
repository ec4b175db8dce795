/**
 * The vehicle a page opens when its address names none: the first that can be reached, else the
 * first (a vehicle whose node of the fleet is cut off cannot be joined). The operator and the
 * developer page both open it.
 */
export function firstVehicle<V extends { readonly id: string; readonly status?: string | undefined }>(vehicles: readonly V[]): V | undefined {
  return vehicles.find((v) => v.status !== "unreachable") ?? vehicles[0];
}
