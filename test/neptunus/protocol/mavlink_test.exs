defmodule Neptunus.Protocol.MAVLinkTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Protocol.MAVLink
  doctest Neptunus.Protocol.MAVLink.CRC

  import Bitwise
  import Neptunus.Test.Properties

  alias Neptunus.Protocol.MAVLink
  alias Neptunus.Protocol.MAVLink.{CRC, Definition, Message, Messages}
  alias Neptunus.Test.MAVLinkGen, as: Gen

  @gcs %{system: 255, component: 190, seq: 0}

  # Frames as pymavlink 2.4.50 writes them (MAVLINK20=1 / MAVLink 1 for the last).
  # ATTITUDE(1234, 0.1, -0.2, 3.0, 0, 0, 0.5) from 1/1 seq 7: trailing zeros of yawspeed kept
  @attitude "FD1C00000701011E0000D2040000CDCCCC3DCDCC4CBE0000404000000000000000000000003FCA58"
  # COMMAND_ACK(400, 0) from 1/1 seq 8: truncated to 2 bytes (result and extensions are zero)
  @ack "FD0200000801014D000090016A27"
  # STATUSTEXT(6, "Arming motors") from 1/1 seq 9
  @statustext "FD0E0000090101FD00000641726D696E67206D6F746F7273E28D"
  # HEARTBEAT(12 submarine, 3 ardupilotmega, 81, 19 MANUAL, 4 active) as MAVLink 1, seq 3
  @heartbeat_v1 "FE0903010100130000000C03510403DAC1"

  # The published CRC_EXTRA of each message (pymavlink's MAVLink_<name>_message.crc_extra).
  @published %{
    heartbeat: {0, 50},
    sys_status: {1, 124},
    system_time: {2, 137},
    set_mode: {11, 89},
    param_request_read: {20, 214},
    param_request_list: {21, 159},
    param_value: {22, 220},
    param_set: {23, 168},
    scaled_pressure: {29, 115},
    attitude: {30, 39},
    local_position_ned: {32, 185},
    global_position_int: {33, 104},
    servo_output_raw: {36, 222},
    rc_channels: {65, 118},
    request_data_stream: {66, 148},
    manual_control: {69, 243},
    vfr_hud: {74, 20},
    command_long: {76, 152},
    command_ack: {77, 143},
    timesync: {111, 34},
    scaled_pressure2: {137, 195},
    battery_status: {147, 154},
    message_interval: {244, 95},
    named_value_float: {251, 170},
    statustext: {253, 83},
    mission_request_list: {43, 132},
    mission_count: {44, 221},
    mission_ack: {47, 153},
    rc_channels_override: {70, 124},
    command_int: {75, 158},
    autopilot_version: {148, 178},
    # development.xml's first revision of the GCS control protocol (not in pymavlink 2.4.50):
    # MAVLINK_MSG_ID_CONTROL_STATUS_CRC of the C library generated from it
    control_status: {512, 184}
  }

  defp decode_all(bytes) do
    {decoder, messages, events} = MAVLink.decode(MAVLink.new(), bytes)
    {messages, events, MAVLink.stats(decoder), decoder}
  end

  defp encode!(name, fields, header \\ @gcs, version \\ 2) do
    {:ok, frame} = MAVLink.encode(name, fields, header, version)
    frame
  end

  # A MAVLink 2 frame with the signed flag, its checksum redone, and a signature appended
  # (the signature bytes are not a real signature: the codec does not verify them).
  defp sign(<<0xFD, length, _incompat, rest::binary>>, link_id, timestamp, signature) do
    <<compat, header::binary-size(6), payload::binary-size(length), _crc::16>> = rest
    checked = <<length, 1, compat, header::binary, payload::binary>>
    <<_::binary-size(6), id::little-24, _::binary>> = checked
    crc = CRC.x25(<<Messages.get(id).crc_extra>>, CRC.x25(checked))
    <<0xFD, checked::binary, crc::little-16, link_id, timestamp::little-48, signature::binary>>
  end

  describe "checksum and definitions" do
    test "X.25 (CRC-16/MCRF4XX) check value" do
      assert CRC.x25("123456789") == 0x6F91
      assert CRC.x25("") == 0xFFFF
      assert CRC.x25("456789", CRC.x25("123")) == 0x6F91
    end

    test "every message's CRC_EXTRA, computed from its declaration, is the published one" do
      assert Map.keys(@published) |> Enum.sort() ==
               Messages.all() |> Enum.map(& &1.name) |> Enum.sort()

      for {name, {id, crc_extra}} <- @published do
        definition = Messages.get(name)
        assert definition.id == id, "#{name} id"
        assert Messages.get(id) == definition
        assert definition.crc_extra == crc_extra, "#{name} CRC_EXTRA #{definition.crc_extra}"
      end
    end

    test "wire order: by type size, largest first, stable; extensions after, as declared" do
      names = fn name -> Enum.map(Messages.get(name).wire, & &1.name) end

      assert names.(:heartbeat) ==
               [:custom_mode, :type, :autopilot, :base_mode, :system_status, :mavlink_version]

      assert names.(:command_long) ==
               [:param1, :param2, :param3, :param4, :param5, :param6, :param7, :command] ++
                 [:target_system, :target_component, :confirmation]

      assert names.(:battery_status) ==
               [:current_consumed, :energy_consumed, :temperature, :voltages, :current_battery] ++
                 [:id, :battery_function, :type, :battery_remaining, :time_remaining] ++
                 [:charge_state, :voltages_ext, :mode, :fault_bitmask]

      assert names.(:manual_control) ==
               [:x, :y, :z, :r, :buttons, :target, :buttons2, :enabled_extensions] ++
                 [:s, :t, :aux1, :aux2, :aux3, :aux4, :aux5, :aux6]

      assert names.(:param_value) ==
               [:param_value, :param_count, :param_index, :param_id, :param_type]
    end

    test "payload lengths: base (MAVLink 1) and with extensions" do
      lengths = fn name -> {Messages.get(name).base_length, Messages.get(name).full_length} end
      assert lengths.(:heartbeat) == {9, 9}
      assert lengths.(:sys_status) == {31, 43}
      assert lengths.(:battery_status) == {36, 54}
      assert lengths.(:manual_control) == {11, 30}
      assert lengths.(:command_ack) == {3, 10}
      assert lengths.(:statustext) == {51, 54}
      assert lengths.(:rc_channels) == {42, 42}
    end

    test "the CRC_EXTRA rule covers array lengths and leaves extensions out" do
      base = [{"uint8_t", "a"}, {"uint16_t[4]", "b"}]
      plain = Definition.build({1, "X", base})

      assert Definition.build({1, "X", base ++ [:ext, {"uint32_t", "c"}]}).crc_extra ==
               plain.crc_extra

      refute Definition.build({1, "X", [{"uint8_t", "a"}, {"uint16_t[5]", "b"}]}).crc_extra ==
               plain.crc_extra

      # by hand: X.25 over "X ", "uint16_t b ", <<4>>, "uint8_t a "
      crc = CRC.x25("uint8_t a ", CRC.x25(<<4>>, CRC.x25("uint16_t b ", CRC.x25("X "))))
      assert plain.crc_extra == bxor(crc &&& 0xFF, crc >>> 8)
    end
  end

  describe "decoding" do
    test "frames written by pymavlink" do
      {messages, events, stats, _} =
        decode_all(Base.decode16!(@attitude <> @ack <> @statustext <> @heartbeat_v1))

      assert events == [{:lost, {1, 1}, 249}]
      assert stats.messages == 4 and stats.garbage_bytes == 0 and stats.bad_checksum == 0

      assert [attitude, ack, text, heartbeat] = messages

      assert %Message{name: :attitude, id: 30, system: 1, component: 1, seq: 7, version: 2} =
               attitude

      assert attitude.fields.time_boot_ms == 1234
      assert_in_delta attitude.fields.roll, 0.1, 1.0e-7
      assert_in_delta attitude.fields.pitch, -0.2, 1.0e-7
      assert attitude.fields.yaw == 3.0 and attitude.fields.yawspeed == 0.5

      assert ack.name == :command_ack and ack.seq == 8

      assert ack.fields == %{
               command: 400,
               result: 0,
               progress: 0,
               result_param2: 0,
               target_system: 0,
               target_component: 0
             }

      assert text.fields == %{severity: 6, text: "Arming motors", id: 0, chunk_seq: 0}

      assert %Message{name: :heartbeat, version: 1, seq: 3, signature: nil} = heartbeat

      assert heartbeat.fields == %{
               type: 12,
               autopilot: 3,
               base_mode: 81,
               custom_mode: 19,
               system_status: 4,
               mavlink_version: 3
             }
    end

    test "a signed frame: link id, timestamp and signature exposed" do
      frame = sign(Base.decode16!(@ack), 7, 0x0000_1234_5678_9A, <<1, 2, 3, 4, 5, 6>>)
      {[message], [], stats, _} = decode_all(frame)

      assert %{
               link_id: 7,
               timestamp: 0x0000_1234_5678_9A,
               signature: <<1, 2, 3, 4, 5, 6>>,
               signed: signed
             } = message.signature

      # the signature covers the frame up to its timestamp
      assert signed == binary_part(frame, 0, byte_size(frame) - 6)

      assert message.fields.command == 400
      assert stats.messages == 1
    end

    test "frames with an incompatibility flag we do not know are dropped" do
      <<0xFD, length, _incompat, rest::binary>> = Base.decode16!(@ack)
      {[], events, stats, _} = decode_all(<<0xFD, length, 0x02, rest::binary>>)
      assert stats.messages == 0
      assert stats.garbage_bytes == byte_size(rest) + 3
      assert events == [{:garbage, byte_size(rest) + 3}]
    end

    test "garbage before, between and after frames is skipped and counted" do
      ack = Base.decode16!(@ack)
      {messages, events, stats, decoder} = decode_all("abc" <> ack <> "\x00\x01" <> ack <> "z")
      assert length(messages) == 2
      # garbage events next to each other in the list are merged
      assert events == [{:garbage, 5}, {:lost, {1, 1}, 255}, {:garbage, 1}]
      assert stats.garbage_bytes == 6
      assert decoder.buffer == ""
    end

    test "a bad checksum drops the frame, counts it, and finds the frame hidden behind it" do
      ack = Base.decode16!(@ack)
      <<head::binary-size(byte_size(ack) - 1), last>> = ack
      bad = <<head::binary, bxor(last, 0xFF)>>
      {messages, events, stats, _} = decode_all(bad <> ack)
      assert [%Message{name: :command_ack}] = messages
      assert [{:bad_checksum, 77}, {:garbage, n}] = events
      assert n == byte_size(ack)
      assert stats.bad_checksum == 1 and stats.garbage_bytes == byte_size(ack)

      # a frame whose length byte was corrupted so that it swallows the next frame
      <<0xFD, _len, rest::binary>> = ack
      {messages, _events, stats, _} = decode_all(<<0xFD, 5, rest::binary>> <> ack)
      assert [%Message{name: :command_ack}] = messages
      assert stats.bad_checksum == 1
    end

    test "an unknown message id is skipped by its length and counted" do
      # a frame of message 42 (MISSION_CURRENT, not defined here) with a 4-byte payload
      unknown = <<0xFD, 4, 0, 0, 3, 1, 1, 42, 0, 0, 1, 2, 3, 4, 0xAB, 0xCD>>
      ack = Base.decode16!(@ack)
      {messages, events, stats, decoder} = decode_all(unknown <> ack)
      assert [%Message{name: :command_ack, seq: 8}] = messages
      assert events == [{:unknown_message, 42, {1, 1}}, {:lost, {1, 1}, 4}]
      assert stats.unknown == 1 and stats.garbage_bytes == 0 and stats.lost == 4
      assert MAVLink.sources(decoder) == %{{1, 1} => %{received: 2, lost: 4, last_seq: 8}}
    end

    test "garbage that looks like an unknown message's header does not swallow the frames after it" do
      acks =
        for seq <- 1..3,
            do:
              encode!(:command_ack, %{command: seq, result: 0}, %{
                system: 1,
                component: 1,
                seq: seq
              })

      # a header of message 42 announcing 30 bytes: its "frame" would end inside the third ack
      fake = <<0xFD, 30, 0, 0, 0, 9, 9, 42, 0, 0>>
      {messages, _events, stats, _} = decode_all(IO.iodata_to_binary([fake | acks]))
      assert Enum.map(messages, & &1.fields.command) == [1, 2, 3]
      assert stats.unknown == 0 and stats.garbage_bytes == byte_size(fake)
    end

    test "an unknown message's frame at the end of the bytes waits for the next byte" do
      unknown = <<0xFD, 4, 0, 0, 3, 1, 1, 42, 0, 0, 1, 2, 3, 4, 0xAB, 0xCD>>
      {decoder, [], []} = MAVLink.decode(MAVLink.new(), unknown)
      assert decoder.buffer == unknown
      ack = Base.decode16!(@ack)

      {decoder, [_ack], [{:unknown_message, 42, {1, 1}}, {:lost, {1, 1}, 4}]} =
        MAVLink.decode(decoder, ack)

      assert MAVLink.stats(decoder).unknown == 1
    end

    test "lost frames are counted per sender, with wrap-around" do
      frames =
        for {system, seq} <- [{1, 254}, {2, 10}, {1, 255}, {1, 2}, {2, 11}, {2, 15}] do
          encode!(:command_ack, %{command: 1, result: 0}, %{
            system: system,
            component: 1,
            seq: seq
          })
        end

      {messages, events, stats, decoder} = decode_all(IO.iodata_to_binary(frames))
      assert length(messages) == 6
      assert events == [{:lost, {1, 1}, 2}, {:lost, {2, 1}, 3}]
      assert stats.lost == 5

      assert MAVLink.sources(decoder) == %{
               {1, 1} => %{received: 3, lost: 2, last_seq: 2},
               {2, 1} => %{received: 3, lost: 3, last_seq: 15}
             }
    end

    test "an incomplete frame waits for the rest, and the buffer stays bounded" do
      ack = Base.decode16!(@ack)
      <<first::binary-size(5), second::binary>> = ack
      {decoder, [], [garbage: 2]} = MAVLink.decode(MAVLink.new(), "xy" <> first)
      assert decoder.buffer == first
      {decoder, [message], []} = MAVLink.decode(decoder, second)
      assert message.fields.command == 400
      assert decoder.buffer == ""

      # the longest frame a header can announce, never completed: at most 279 bytes held
      {decoder, [], []} = MAVLink.decode(MAVLink.new(), <<0xFD, 255, 1, 0, 0, 1, 1, 0, 0, 0>>)

      {decoder, [], []} = MAVLink.decode(decoder, :binary.copy(<<1>>, 269))
      assert byte_size(decoder.buffer) == 279
      {decoder, [], [{:bad_checksum, 0}, {:garbage, 280}]} = MAVLink.decode(decoder, <<1>>)
      assert decoder.buffer == ""
    end

    test "a shorter payload is zero-extended, a longer one read up to what we know" do
      {:ok, frame} =
        MAVLink.encode(:manual_control, %{target: 0, x: 0, y: 0, z: 500, r: 0, buttons: 0}, @gcs)

      # MANUAL_CONTROL's wire order is x y z r buttons target …: z = 500 is the last non-zero byte
      assert byte_size(frame) == 12 + 6
      {[message], [], _, _} = decode_all(frame)
      assert message.fields.z == 500 and message.fields.aux6 == 0 and message.fields.s == 0

      # a sender with more extension fields than we know (two extra bytes after aux6)
      payload = <<0::64, 0, 0, 1, 0::size(19 * 8), 7, 7>>
      assert byte_size(payload) == 32
      checked = <<32, 0, 0, 0, 1, 1, 69::little-24, payload::binary>>
      crc = CRC.x25(<<243>>, CRC.x25(checked))
      {[message], [], _, _} = decode_all(<<0xFD, checked::binary, crc::little-16>>)
      assert message.fields.target == 1 and message.fields.aux6 == 0
    end

    test "NaN and infinities in float fields" do
      fields = %{
        time_boot_ms: 1,
        press_abs: :nan,
        press_diff: :infinity,
        temperature: -5,
        temperature_press_diff: 0
      }

      frame = encode!(:scaled_pressure, fields)
      {[message], [], _, _} = decode_all(frame)
      assert message.fields == fields

      frame = encode!(:system_time, %{time_unix_usec: 0xFFFFFFFFFFFFFFFF, time_boot_ms: 0})
      {[message], [], _, _} = decode_all(frame)
      assert message.fields.time_unix_usec == 0xFFFFFFFFFFFFFFFF

      # a signalling NaN and a negative-mantissa NaN are NaN too
      payload = <<1::little-32, 0x7F800001::little-32, 0xFFC00001::little-32, 0::16>>
      checked = <<14, 0, 0, 0, 1, 1, 29::little-24, payload::binary>>
      crc = CRC.x25(<<115>>, CRC.x25(checked))
      {[message], [], _, _} = decode_all(<<0xFD, checked::binary, crc::little-16>>)
      assert message.fields.press_abs == :nan and message.fields.press_diff == :nan
    end
  end

  describe "encoding" do
    test "MAVLink 2 truncates trailing zeros, keeping one byte; MAVLink 1 sends the base payload" do
      zero = %{target_system: 0, target_component: 0}
      frame = encode!(:param_request_list, zero)
      assert <<0xFD, 1, 0, 0, 0, 255, 190, 21, 0, 0, 0, _::16>> = frame

      fields = %{command: 400, result: 0, progress: 0, result_param2: 0, target_system: 1}
      assert <<0xFD, 9, _::binary>> = encode!(:command_ack, fields)
      assert <<0xFD, 2, _::binary>> = encode!(:command_ack, %{fields | target_system: 0})

      assert <<0xFE, 3, 0, 255, 190, 77, 144, 1, 0, _::16>> =
               encode!(:command_ack, fields, @gcs, 1)
    end

    test "frames match pymavlink's byte for byte" do
      assert encode!(
               :attitude,
               %{
                 time_boot_ms: 1234,
                 roll: 0.1,
                 pitch: -0.2,
                 yaw: 3.0,
                 rollspeed: 0.0,
                 pitchspeed: 0.0,
                 yawspeed: 0.5
               },
               %{system: 1, component: 1, seq: 7}
             ) == Base.decode16!(@attitude)

      assert encode!(:statustext, %{severity: 6, text: "Arming motors"}, %{
               system: 1,
               component: 1,
               seq: 9
             }) == Base.decode16!(@statustext)

      heartbeat = %{type: 12, autopilot: 3, base_mode: 81, custom_mode: 19, system_status: 4}

      assert encode!(:heartbeat, heartbeat, %{system: 1, component: 1, seq: 3}, 1) ==
               Base.decode16!(@heartbeat_v1)

      assert encode!(
               30,
               %{
                 time_boot_ms: 1234,
                 roll: 0.1,
                 pitch: -0.2,
                 yaw: 3,
                 rollspeed: 0,
                 pitchspeed: 0,
                 yawspeed: 0.5
               },
               %{system: 1, component: 1, seq: 7}
             ) == Base.decode16!(@attitude)
    end

    test "bad input is a clear error" do
      ack = %{command: 400, result: 0}
      assert MAVLink.encode(:nope, ack, @gcs) == {:error, {:unknown_message, :nope}}
      assert MAVLink.encode(9999, ack, @gcs) == {:error, {:unknown_message, 9999}}

      assert MAVLink.encode(:command_ack, ack, %{@gcs | seq: 256}) ==
               {:error, {:bad_header, %{@gcs | seq: 256}}}

      assert MAVLink.encode(:command_ack, ack, %{system: 1}) ==
               {:error, {:bad_header, %{system: 1}}}

      assert MAVLink.encode(:command_ack, ack, @gcs, 3) == {:error, {:bad_version, 3}}
      assert MAVLink.encode(:command_ack, [], @gcs) == {:error, {:bad_fields, []}}

      assert MAVLink.encode(:command_ack, %{command: 400}, @gcs) ==
               {:error, {:missing_field, :result}}

      assert MAVLink.encode(:command_ack, Map.put(ack, :foo, 1), @gcs) ==
               {:error, {:unknown_field, :foo}}

      for {field, value} <- [{:command, 65_536}, {:command, -1}, {:command, 1.0}, {:result, nil}] do
        assert MAVLink.encode(:command_ack, Map.put(ack, field, value), @gcs) ==
                 {:error, {:bad_value, field, value}}
      end

      text = %{severity: 6, text: String.duplicate("a", 51)}
      assert {:error, {:bad_value, :text, _}} = MAVLink.encode(:statustext, text, @gcs)
      text = %{severity: 6, text: "a\0b"}
      assert {:error, {:bad_value, :text, _}} = MAVLink.encode(:statustext, text, @gcs)

      assert {:ok, _} =
               MAVLink.encode(:statustext, %{text | text: String.duplicate("a", 50)}, @gcs)

      battery = %{
        id: 0,
        battery_function: 0,
        type: 0,
        temperature: 0,
        voltages: List.duplicate(0, 9),
        current_battery: 0,
        current_consumed: 0,
        energy_consumed: 0,
        battery_remaining: 0
      }

      assert {:error, {:bad_value, :voltages, _}} = MAVLink.encode(:battery_status, battery, @gcs)

      assert {:ok, _} =
               MAVLink.encode(
                 :battery_status,
                 %{battery | voltages: List.duplicate(65_535, 10)},
                 @gcs
               )

      attitude = %{
        time_boot_ms: 0,
        roll: 1.0e39,
        pitch: 0,
        yaw: 0,
        rollspeed: 0,
        pitchspeed: 0,
        yawspeed: 0
      }

      assert MAVLink.encode(:attitude, attitude, @gcs) == {:error, {:bad_value, :roll, 1.0e39}}
    end

    test "next_seq wraps" do
      assert MAVLink.next_seq(0) == 1
      assert MAVLink.next_seq(255) == 0
    end
  end

  # ── properties ─────────────────────────────────────────────────────────────────────────

  describe "properties" do
    test "random bytes never crash and give the documented shape, every byte accounted for" do
      check(
        {:proper_types.list(:proper_types.binary()), :proper_types.binary()},
        fn {chunks, extra} ->
          {decoder, ok?} =
            Enum.reduce(chunks ++ [extra], {MAVLink.new(), true}, fn chunk, {decoder, ok?} ->
              {decoder, messages, events} = MAVLink.decode(decoder, chunk)

              shape? =
                is_list(messages) and Enum.all?(messages, &match?(%Message{}, &1)) and
                  Enum.all?(events, fn
                    {:garbage, n} ->
                      is_integer(n) and n > 0

                    {:bad_checksum, id} ->
                      is_integer(id)

                    {:unknown_message, id, {s, c}} ->
                      is_integer(id) and s in 0..255 and c in 0..255

                    {:lost, {_, _}, n} ->
                      n in 1..255

                    _ ->
                      false
                  end)

              {decoder, ok? and shape?}
            end)

          ok? and byte_size(decoder.buffer) <= 280 and
            MAVLink.stats(decoder) |> Map.values() |> Enum.all?(&(&1 >= 0))
        end,
        300
      )
    end

    test "every message round-trips through encode and decode (MAVLink 2 and 1)" do
      check(
        Gen.framed(),
        fn {{name, fields}, header, version} ->
          {:ok, frame} = MAVLink.encode(name, fields, header, version)
          {[message], [], _stats, decoder} = decode_all(frame)

          message.name == name and message.fields == Gen.as_received(name, fields, version) and
            message.system == header.system and message.component == header.component and
            message.seq == header.seq and message.version == version and
            decoder.buffer == "" and MAVLink.stats(decoder).garbage_bytes == 0
        end,
        1000
      )
    end

    test "frames split into arbitrary chunks decode the same as in one piece" do
      check(
        {:proper_types.non_empty(:proper_types.list(Gen.framed())),
         :proper_types.list(:proper_types.integer(0, 2000)), :proper_types.binary()},
        fn {messages, cuts, noise} ->
          frames =
            for {{name, fields}, header, version} <- messages do
              {:ok, frame} = MAVLink.encode(name, fields, header, version)
              frame
            end

          # noise in front (without a start byte it cannot hide a frame)
          noise = for <<b <- noise>>, b not in [0xFD, 0xFE], into: <<>>, do: <<b>>
          stream = IO.iodata_to_binary([noise | frames])
          {whole, whole_events, whole_stats, _} = decode_all(stream)

          cuts = cuts |> Enum.map(&rem(&1, byte_size(stream) + 1)) |> Enum.sort() |> Enum.uniq()

          {chunks, rest} =
            Enum.map_reduce(Enum.reverse(cuts), stream, fn cut, rest ->
              <<head::binary-size(cut), tail::binary>> = rest
              {tail, head}
            end)

          {decoder, got, events} =
            Enum.reduce([rest | Enum.reverse(chunks)], {MAVLink.new(), [], []}, fn chunk,
                                                                                   {d, m, e} ->
              {d, more, ev} = MAVLink.decode(d, chunk)
              {d, m ++ more, e ++ ev}
            end)

          merge = fn events ->
            Enum.chunk_by(events, &match?({:garbage, _}, &1))
            |> Enum.flat_map(fn
              [{:garbage, _} | _] = run ->
                [{:garbage, run |> Enum.map(&elem(&1, 1)) |> Enum.sum()}]

              other ->
                other
            end)
          end

          length(whole) == length(messages) and got == whole and
            merge.(events) == merge.(whole_events) and MAVLink.stats(decoder) == whole_stats
        end,
        300
      )
    end

    test "a mutated frame is dropped and counted, or decoded if its checksum still holds; never raised" do
      check(
        {Gen.framed(),
         :proper_types.list(
           {:proper_types.oneof([:set, :insert, :delete]), :proper_types.integer(0, 300),
            :proper_types.integer(0, 255)}
         )},
        fn {{{name, fields}, header, version}, mutations} ->
          {:ok, frame} = MAVLink.encode(name, fields, header, version)

          mutated =
            Enum.reduce(mutations, frame, fn {kind, at, byte}, bytes ->
              at = rem(at, byte_size(bytes) + 1)
              <<head::binary-size(at), tail::binary>> = bytes

              case {kind, tail} do
                {:set, <<_, rest::binary>>} -> <<head::binary, byte, rest::binary>>
                {:delete, <<_, rest::binary>>} -> head <> rest
                _ -> <<head::binary, byte, tail::binary>>
              end
            end)

          # zeros after it complete any frame the mutation lengthened
          {messages, events, stats, _} = decode_all(mutated <> :binary.copy(<<0>>, 300))

          counted? =
            stats.messages == length(messages) and
              stats.bad_checksum == Enum.count(events, &match?({:bad_checksum, _}, &1)) and
              stats.unknown == Enum.count(events, &match?({:unknown_message, _, _}, &1)) and
              stats.garbage_bytes ==
                events
                |> Enum.flat_map(fn
                  {:garbage, n} -> [n]
                  _ -> []
                end)
                |> Enum.sum()

          single_substitution? = match?([{:set, _, _}], mutations)

          # one changed byte is always caught by the checksum (a CRC-16 detects every burst
          # of up to 16 bits), so what decodes is the message as sent
          intact? =
            not single_substitution? or
              Enum.all?(
                messages,
                &(&1.name == name and &1.fields == Gen.as_received(name, fields, version))
              )

          counted? and intact? and
            (messages != [] or mutated == frame or
               stats.bad_checksum + stats.unknown + stats.garbage_bytes > 0)
        end,
        1000
      )
    end
  end
end
