defmodule Neptunus.Protocol.MAVLink.SigningTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Protocol.MAVLink.Signing

  import Neptunus.Test.Properties

  alias Neptunus.Protocol.MAVLink
  alias Neptunus.Protocol.MAVLink.Signing
  alias Neptunus.Test.MAVLinkGen, as: Gen

  # pymavlink 2.4.50, MAVLINK20=1: HEARTBEAT(12, 0, 129, 19, 4) from 1/1 seq 5, signed with
  # SHA-256("neptunus") on link 3 at timestamp 123456789, and the same frame unsigned
  @signed "FD090100050101000000130000000C008104035F3A0315CD5B070000612278111E7F"
  @unsigned "FD090000050101000000130000000C00810403B8C2"
  @key Signing.key_from_passphrase("neptunus")

  defp decode_one(frame) do
    {_decoder, [message], []} = MAVLink.decode(MAVLink.new(), frame)
    message
  end

  defp key, do: :proper_types.binary(32)

  test "the key of a passphrase is its SHA-256, as MAVProxy derives it" do
    assert Base.encode16(@key, case: :lower) ==
             "895924213b1ee75316e69e9d53c3c9b9affc9fc79a81dc4b3d5719776d21ae7a"
  end

  test "signing gives the frame pymavlink signs, byte for byte" do
    unsigned = Base.decode16!(@unsigned)
    assert Signing.sign(unsigned, 5, @key, 3, 123_456_789) == Base.decode16!(@signed)
  end

  test "a frame pymavlink signed verifies with its key, not with another or unsigned" do
    message = decode_one(Base.decode16!(@signed))
    assert message.signature.link_id == 3
    assert message.signature.timestamp == 123_456_789
    assert Signing.verify(message, @key)
    refute Signing.verify(message, Signing.key_from_passphrase("neptunus "))
    refute Signing.verify(decode_one(Base.decode16!(@unsigned)), @key)
  end

  test "restamping changes the sequence number and nothing else" do
    message = decode_one(MAVLink.restamp(Base.decode16!(@unsigned), 200))
    assert message.seq == 200
    assert message.fields == decode_one(Base.decode16!(@unsigned)).fields
    assert message.signature == nil
  end

  describe "replays" do
    test "a stream must go forward; a new one may be at most a minute behind our clock" do
      assert Signing.replay(nil, 100, 100) == :ok
      assert Signing.replay(nil, 100, 6_000_100) == :ok
      assert Signing.replay(nil, 99, 6_000_100) == {:error, :too_old}
      # a sender ahead of our clock is fine (its clock, not ours, starts its stream)
      assert Signing.replay(nil, 9_000_000, 0) == :ok
      assert Signing.replay(100, 101, 0) == :ok
      assert Signing.replay(100, 100, 0) == {:error, :replayed}
      assert Signing.replay(100, 3, 0) == {:error, :replayed}
    end

    test "timestamps from the clock: 10 µs units since 2015, never below 0" do
      assert Signing.timestamp(1_420_070_400_000_000) == 0
      assert Signing.timestamp(0) == 0
      assert Signing.timestamp(1_420_070_400_000_000 + 1_000_000) == 100_000
    end
  end

  describe "properties" do
    test "every message signed with any key, link and timestamp verifies with that key only" do
      check(
        {Gen.message(), Gen.header(), key(), key(), :proper_types.integer(0, 255),
         :proper_types.integer(0, 0xFFFFFFFFFFFF)},
        fn {{name, fields}, header, key, other, link_id, timestamp} ->
          {:ok, frame} = MAVLink.encode(name, fields, header)
          signed = Signing.sign(frame, header.seq, key, link_id, timestamp)
          message = decode_one(signed)

          message.name == name and message.fields == fields and message.seq == header.seq and
            message.signature.link_id == link_id and message.signature.timestamp == timestamp and
            Signing.verify(message, key) and (other == key or not Signing.verify(message, other))
        end,
        300
      )
    end

    test "changing any byte of a signed frame breaks it: dropped, or its signature fails" do
      check(
        {Gen.message(), Gen.header(), key(), :proper_types.integer(0, 10_000),
         :proper_types.integer(1, 255)},
        fn {{name, fields}, header, key, at, flip} ->
          {:ok, frame} = MAVLink.encode(name, fields, header)
          signed = Signing.sign(frame, header.seq, key, 1, 42)
          at = rem(at, byte_size(signed))
          <<head::binary-size(at), byte, tail::binary>> = signed
          mutated = <<head::binary, Bitwise.bxor(byte, flip), tail::binary>>

          {_decoder, messages, _events} = MAVLink.decode(MAVLink.new(), mutated)
          # whatever still decodes from it (a checksum that holds by chance) is not signed right
          Enum.all?(messages, &(not Signing.verify(&1, key)))
        end,
        500
      )
    end

    test "restamping keeps the message and sets the sequence number" do
      check({Gen.message(), Gen.header(), :proper_types.integer(0, 255)}, fn {{name, fields},
                                                                              header, seq} ->
        {:ok, frame} = MAVLink.encode(name, fields, header)
        message = decode_one(MAVLink.restamp(frame, seq))

        message.name == name and message.fields == fields and message.seq == seq and
          message.system == header.system and message.signature == nil
      end)
    end

    test "timestamps a link sends always grow" do
      check(
        :proper_types.list(:proper_types.integer(0, 1_000_000)),
        fn clocks ->
          {sent, _} =
            Enum.map_reduce(clocks, 0, fn now, last ->
              next = Signing.next_timestamp(now, last)
              {next, next}
            end)

          sent == Enum.sort(sent) and sent == Enum.uniq(sent) and
            Enum.all?(Enum.zip(clocks, sent), fn {now, ts} -> ts >= now end)
        end
      )
    end
  end
end
