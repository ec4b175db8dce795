"""pymavlink's side of the MAVLink interoperability tests (test/neptunus/protocol/mavlink_interop_test.exs).

Run with the project's virtualenv (`make setup` creates .venv with the pinned pymavlink):

  .venv/bin/python test/support/pymavlink_interop.py info NAME...   the definitions pymavlink has
  .venv/bin/python test/support/pymavlink_interop.py encode SEED NAME...
                                                                   frames pymavlink writes
  .venv/bin/python test/support/pymavlink_interop.py decode FILE  what pymavlink reads in the
                                                                   frames of FILE (a JSON list of
                                                                   {"frame": HEX, "key"?: HEX}; a
                                                                   frame with a key must be signed
                                                                   with it)

Every answer is one JSON document on stdout. Values travel as MAVLink defines them: integers,
floats (NaN and infinities as the strings "nan", "infinity", "neg_infinity"), arrays as lists,
char[N] strings as {"hex": "..."} (their bytes, without the NUL padding).
"""

import json
import math
import os
import random
import struct
import sys

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

INT_RANGES = {
    "uint8_t": (0, 0xFF),
    "int8_t": (-0x80, 0x7F),
    "uint16_t": (0, 0xFFFF),
    "int16_t": (-0x8000, 0x7FFF),
    "uint32_t": (0, 0xFFFFFFFF),
    "int32_t": (-0x80000000, 0x7FFFFFFF),
    "uint64_t": (0, 0xFFFFFFFFFFFFFFFF),
    "int64_t": (-0x8000000000000000, 0x7FFFFFFFFFFFFFFF),
}


def message_class(name):
    return getattr(mavlink, "MAVLink_%s_message" % name)


def to_json(value):
    if isinstance(value, bytes):
        return {"hex": value.hex().upper()}
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "infinity" if value > 0 else "neg_infinity"
        return value
    if isinstance(value, list):
        return [to_json(v) for v in value]
    return value


def fields_of(message):
    """The message's field values; a char[N] field's raw bytes (pymavlink keeps them in
    `_NAME_raw` beside a decoded str)."""
    return {
        name: to_json(getattr(message, "_%s_raw" % name, getattr(message, name)))
        for name in message.get_fieldnames()
    }


def float32(value):
    return struct.unpack("<f", struct.pack("<f", value))[0]


def random_value(rng, field_type, sparse):
    if sparse and rng.random() < 0.6:
        return 0.0 if field_type in ("float", "double") else 0
    if field_type in INT_RANGES:
        low, high = INT_RANGES[field_type]
        return rng.randint(low, high)
    if rng.random() < 0.05:
        return rng.choice([math.nan, math.inf, -math.inf])
    if field_type == "float":
        return float32(rng.uniform(-1.0e6, 1.0e6) if rng.random() < 0.8 else rng.uniform(-3.0e38, 3.0e38))
    return rng.uniform(-1.0e300, 1.0e300)


def array_lengths(cls):
    """Array length (0: not an array) by field name (pymavlink lists them in wire order)."""
    return dict(zip(cls.ordered_fieldnames, cls.array_lengths))


def random_fields(rng, cls, sparse):
    values = []
    lengths = array_lengths(cls)
    for name, field_type in zip(cls.fieldnames, cls.fieldtypes):
        length = lengths[name]
        if field_type == "char":
            size = 0 if sparse and rng.random() < 0.6 else rng.randint(0, length)
            values.append(bytes(rng.randint(1, 255) for _ in range(size)))
        elif length:
            values.append([random_value(rng, field_type, sparse) for _ in range(length)])
        else:
            values.append(random_value(rng, field_type, sparse))
    return values


def untruncated(message, seq):
    """The MAVLink 2 frame of `message` from 1/1 with its whole payload, trailing zeros
    included (pymavlink itself always truncates)."""
    full = full_payload(message)
    # the class's id: some messages have a field named `id`
    header = mavlink.MAVLink_header(type(message).id, mlen=len(full), seq=seq, srcSystem=1, srcComponent=1)
    body = header.pack() + full
    crc = mavlink.x25crc(body[1:])
    crc.accumulate(struct.pack("B", message.crc_extra))
    return body + struct.pack("<H", crc.crc)


def full_payload(message):
    """The message's payload before truncation, as pymavlink's own packer writes it."""
    captured = {}
    original = message._pack

    def capture(mav, crc_extra, payload, force_mavlink1=False):
        captured["payload"] = payload
        return original(mav, crc_extra, payload, force_mavlink1=force_mavlink1)

    message._pack = capture
    try:
        message.pack(mavlink.MAVLink(None, 1, 1))
    finally:
        del message._pack
    return bytes(captured["payload"])


def encode(seed, names):
    rng = random.Random(seed)
    frames = []
    seq = 0
    for name in names:
        cls = message_class(name)
        for sparse in (False, True):
            for version in (2, 1):
                system, component = rng.randint(0, 255), rng.randint(0, 255)
                mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=component)
                mav.seq = seq
                message = cls(*random_fields(rng, cls, sparse))
                frame = message.pack(mav, force_mavlink1=(version == 1))
                frames.append(
                    {
                        "name": name,
                        "kind": "pymavlink v%d%s" % (version, " sparse" if sparse else ""),
                        "frame": frame.hex().upper(),
                        "version": version,
                        "system": system,
                        "component": component,
                        "seq": seq,
                        "fields": fields_of(message),
                        "signature": None,
                    }
                )
                seq = (seq + 1) % 256

        # a MAVLink 2 frame whose payload keeps its trailing zero bytes
        message = cls(*random_fields(rng, cls, True))
        frame = untruncated(message, seq)
        frames.append(
            {
                "name": name,
                "kind": "untruncated v2",
                "frame": frame.hex().upper(),
                "version": 2,
                "system": 1,
                "component": 1,
                "seq": seq,
                "fields": fields_of(message),
                "signature": None,
            }
        )
        seq = (seq + 1) % 256

        # a signed MAVLink 2 frame
        message = cls(*random_fields(rng, cls, False))
        mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        mav.seq = seq
        key = bytes(rng.randint(0, 255) for _ in range(32))
        mav.signing.secret_key = key
        mav.signing.link_id = rng.randint(0, 255)
        mav.signing.timestamp = rng.randint(0, 2**48 - 2)
        mav.signing.sign_outgoing = True
        link_id, timestamp = mav.signing.link_id, mav.signing.timestamp
        frame = message.pack(mav)
        frames.append(
            {
                "name": name,
                "kind": "signed v2",
                "frame": frame.hex().upper(),
                "version": 2,
                "system": 1,
                "component": 1,
                "seq": seq,
                "fields": fields_of(message),
                "signature": {
                    "link_id": link_id,
                    "timestamp": timestamp,
                    "signature": frame[-6:].hex().upper(),
                    "key": key.hex().upper(),
                },
            }
        )
        seq = (seq + 1) % 256
    return frames


def decode(frames):
    results = []
    for entry in frames:
        mav = mavlink.MAVLink(None)
        if "key" in entry:
            # pymavlink then checks the signature (an unsigned or wrongly signed frame is an
            # error), and the timestamp against its own, 0 here
            mav.signing.secret_key = bytes.fromhex(entry["key"])
            mav.signing.timestamp = 0
        data = bytes.fromhex(entry["frame"])
        try:
            messages = mav.parse_buffer(data) or []
        except mavlink.MAVError as error:
            results.append({"error": str(error)})
            continue
        if len(messages) != 1 or mav.total_receive_errors != 0:
            results.append({"error": "parsed %d messages, %d errors" % (len(messages), mav.total_receive_errors)})
            continue
        message = messages[0]
        if message.get_type() == "BAD_DATA" or isinstance(message, mavlink.MAVLink_unknown):
            results.append({"error": "bad data: %r" % message})
            continue
        results.append(
            {
                "name": message.get_type().lower(),
                "version": 1 if data[0] == mavlink.PROTOCOL_MARKER_V1 else 2,
                "system": message.get_srcSystem(),
                "component": message.get_srcComponent(),
                "seq": message.get_seq(),
                "crc": message.get_crc(),
                "fields": fields_of(message),
            }
        )
    return results


def info(names):
    result = {}
    for name in names:
        cls = message_class(name)
        result[name] = {
            "id": cls.id,
            "crc_extra": cls.crc_extra,
            "fieldnames": list(cls.fieldnames),
            "ordered_fieldnames": list(cls.ordered_fieldnames),
            "fieldtypes": list(cls.fieldtypes),
            "array_lengths": array_lengths(cls),
        }
    return result


def main(argv):
    command = argv[1] if len(argv) > 1 else ""
    if command == "info":
        answer = info(argv[2:])
    elif command == "encode":
        answer = encode(int(argv[2]), argv[3:])
    elif command == "decode":
        with open(argv[2]) as file:
            answer = decode(json.load(file))
    else:
        sys.stderr.write(__doc__)
        return 2
    json.dump(answer, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
