// The few MAVLink 2 frames the ground station benches send (bench/gcs_latency), built by hand
// from the published message definitions: HEARTBEAT, MANUAL_CONTROL, COMMAND_LONG; and a
// count of the frames in a datagram. Unsigned, not truncated (a receiver accepts both).

const CRC_EXTRA = { 0: 50, 69: 243, 76: 152, 77: 143 };

/** CRC-16/MCRF4XX ("X.25") of `bytes`, then of `extra`. */
export function crc(bytes, extra) {
  let c = 0xffff;
  const add = (b) => {
    let t = (b ^ (c & 0xff)) & 0xff;
    t = (t ^ (t << 4)) & 0xff;
    c = ((c >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xffff;
  };
  for (const b of bytes) add(b);
  if (extra != null) add(extra);
  return c;
}

/** A MAVLink 2 frame of message `id` with `payload` (a Buffer in wire order). */
export function frame(id, payload, { sysid = 255, compid = 190, seq = 0 } = {}) {
  const f = Buffer.alloc(12 + payload.length);
  f[0] = 0xfd;
  f[1] = payload.length;
  f[4] = seq & 0xff;
  f[5] = sysid;
  f[6] = compid;
  f[7] = id & 0xff;
  f[8] = (id >> 8) & 0xff;
  f[9] = (id >> 16) & 0xff;
  payload.copy(f, 10);
  f.writeUInt16LE(crc(f.subarray(1, 10 + payload.length), CRC_EXTRA[id]), 10 + payload.length);
  return f;
}

/** HEARTBEAT of a ground station (MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, MAV_STATE_ACTIVE). */
export function heartbeat(opts) {
  return frame(0, Buffer.from([0, 0, 0, 0, 6, 8, 0, 4, 3]), opts);
}

/** MANUAL_CONTROL to system `target`: x, y, z, r (ArduSub's axes), no buttons. */
export function manualControl(target, { x = 0, y = 0, z = 500, r = 0 }, opts) {
  const p = Buffer.alloc(11);
  p.writeInt16LE(x, 0);
  p.writeInt16LE(y, 2);
  p.writeInt16LE(z, 4);
  p.writeInt16LE(r, 6);
  p.writeUInt16LE(0, 8);
  p[10] = target;
  return frame(69, p, opts);
}

/** COMMAND_LONG `command` to system `target`, component 1, with up to 7 params. */
export function commandLong(target, command, params, opts) {
  const p = Buffer.alloc(33);
  for (let i = 0; i < 7; i++) p.writeFloatLE(params[i] ?? 0, 4 * i);
  p.writeUInt16LE(command, 28);
  p[30] = target;
  p[31] = 1;
  return frame(76, p, opts);
}

/** The frames of a datagram: `{id, sysid, payload}` (payload zero-padded to `pad` bytes). */
export function frames(buf, pad = 0) {
  const out = [];
  let i = 0;
  while (i + 12 <= buf.length) {
    if (buf[i] !== 0xfd) { i++; continue; }
    const len = buf[i + 1];
    const size = 12 + len + (buf[i + 2] & 1 ? 13 : 0);
    if (i + size > buf.length) break;
    const id = buf[i + 7] | (buf[i + 8] << 8) | (buf[i + 9] << 16);
    const payload = Buffer.alloc(Math.max(len, pad));
    buf.copy(payload, 0, i + 10, i + 10 + len);
    out.push({ id, sysid: buf[i + 5], payload });
    i += size;
  }
  return out;
}
