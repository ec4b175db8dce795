"""Reads an MCAP file with the `mcap` package (PyPI), the reader the robotics tools use, and
prints what the tests compare with the recording, as JSON:

    {"topics": {topic: {"schema", "encoding", "count", "times": [log_time ns...]}},
     "statistics": {"messages", "chunks", "channels": {topic: count}},
     "linear": {topic: count}, "metadata": {name: {key: value}},
     "video": {"keyframes", "keyframes_with_sps", "annexb", "bytes"}}

Both ways of reading: through the summary and chunk indexes (SeekingReader, CRCs checked)
and straight through the file (NonSeekingReader, CRCs checked). Usage: mcap_read.py FILE
"""
import base64
import json
import sys

from mcap.reader import NonSeekingReader, SeekingReader


def main(path):
    out = {"topics": {}, "linear": {}, "metadata": {}}
    video = {"keyframes": 0, "keyframes_with_sps": 0, "annexb": True, "bytes": 0}

    with open(path, "rb") as f:
        reader = SeekingReader(f, validate_crcs=True)
        summary = reader.get_summary()
        stats = summary.statistics
        out["statistics"] = {
            "messages": stats.message_count,
            "chunks": stats.chunk_count,
            "channels": {
                summary.channels[ch].topic: n for ch, n in stats.channel_message_counts.items()
            },
        }
        last = 0
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            if message.log_time < last:
                raise SystemExit("messages out of log time order")
            last = message.log_time
            topic = out["topics"].setdefault(
                channel.topic,
                {"schema": schema.name, "encoding": schema.encoding, "count": 0, "times": []},
            )
            topic["count"] += 1
            topic["times"].append(message.log_time)
            value = json.loads(message.data)
            if channel.topic == "/camera":
                data = base64.b64decode(value["data"])
                video["bytes"] += len(data)
                if value["format"] == "h264":
                    video["annexb"] = video["annexb"] and data[:4] == b"\x00\x00\x00\x01"
                    nal_types = nals(data)
                    if 5 in nal_types:
                        video["keyframes"] += 1
                        if 7 in nal_types and 8 in nal_types:
                            video["keyframes_with_sps"] += 1
        for record in reader.iter_metadata():
            out["metadata"][record.name] = record.metadata

    with open(path, "rb") as f:
        for _schema, channel, _message in NonSeekingReader(f, validate_crcs=True).iter_messages():
            out["linear"][channel.topic] = out["linear"].get(channel.topic, 0) + 1

    out["video"] = video
    print(json.dumps(out))


def nals(data):
    """The NAL unit types of an Annex B access unit."""
    types = []
    i = 0
    while True:
        i = data.find(b"\x00\x00\x01", i)
        if i < 0 or i + 3 >= len(data):
            return types
        types.append(data[i + 3] & 0x1F)
        i += 3


if __name__ == "__main__":
    main(sys.argv[1])
