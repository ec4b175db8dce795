defmodule Neptunus.Protocol.MAVLinkInteropTest do
  # Our codec against pymavlink (the reference Python implementation, from PyPI, pinned in the
  # Makefile and installed by `make setup` into .venv/): the definitions agree, pymavlink's
  # frames decode to the same fields here, and our frames parse in pymavlink with valid
  # checksums and the same fields.
  use ExUnit.Case, async: true

  @moduletag :external
  @moduletag timeout: 120_000

  alias Neptunus.Protocol.MAVLink
  alias Neptunus.Protocol.MAVLink.{Messages, Signing}
  alias Neptunus.Test.MAVLinkGen
  alias Neptunus.Test.PyMAVLink

  # CONTROL_STATUS comes from a revision of development.xml the pinned pymavlink does not have
  # (Neptunus.Protocol.MAVLink.Messages); its CRC_EXTRA is checked in mavlink_test.exs
  @not_in_pymavlink [:control_status]

  defp definitions, do: Enum.reject(Messages.all(), &(&1.name in @not_in_pymavlink))
  defp names, do: Enum.map(definitions(), &Atom.to_string(&1.name))

  test "the messages pymavlink does not define are the ones we know it lacks" do
    {output, status} =
      System.cmd(
        PyMAVLink.python!(),
        [
          "-c",
          "from pymavlink.dialects.v20 import development as d; " <>
            "print(hasattr(d, 'MAVLink_control_status_message'), " <>
            "hasattr(d, 'MAV_CMD_REQUEST_OPERATOR_CONTROL'))"
        ],
        env: [{"MAVLINK20", "1"}]
      )

    assert {output, status} == {"False False\n", 0},
           "pymavlink now defines CONTROL_STATUS / MAV_CMD_REQUEST_OPERATOR_CONTROL: " <>
             "check their declarations against it (Neptunus.Protocol.MAVLink.Messages)"
  end

  test "every definition agrees with pymavlink's: id, CRC_EXTRA, fields, wire order, arrays" do
    info = PyMAVLink.run!(["info" | names()])

    for definition <- definitions() do
      theirs = Map.fetch!(info, Atom.to_string(definition.name))
      name = definition.name
      assert theirs["id"] == definition.id, "#{name} id"
      assert theirs["crc_extra"] == definition.crc_extra, "#{name} CRC_EXTRA"
      assert theirs["fieldnames"] == Enum.map(definition.fields, &Atom.to_string(&1.name))
      assert theirs["ordered_fieldnames"] == Enum.map(definition.wire, &Atom.to_string(&1.name))

      for field <- definition.fields do
        assert theirs["array_lengths"][Atom.to_string(field.name)] ==
                 field.length || 0,
               "#{name}.#{field.name} array length"
      end
    end
  end

  test "frames pymavlink writes (v2, v1, truncated, untruncated, signed) decode to its fields" do
    frames = PyMAVLink.run!(["encode", "17" | names()])
    # every message in six kinds
    assert length(frames) == 6 * length(definitions())

    stream = frames |> Enum.map(&Base.decode16!(&1["frame"])) |> IO.iodata_to_binary()
    {decoder, messages, events} = MAVLink.decode(MAVLink.new(), stream)

    assert MAVLink.stats(decoder) |> Map.take([:garbage_bytes, :bad_checksum, :unknown]) ==
             %{garbage_bytes: 0, bad_checksum: 0, unknown: 0}

    assert Enum.all?(events, &match?({:lost, _, _}, &1))
    assert length(messages) == length(frames)

    for {frame, message} <- Enum.zip(frames, messages) do
      name = String.to_atom(frame["name"])
      what = "#{frame["kind"]} #{name}: #{frame["frame"]}"
      assert message.name == name, what
      assert message.version == frame["version"], what

      assert {message.system, message.component, message.seq} ==
               {frame["system"], frame["component"], frame["seq"]},
             what

      assert message.fields == PyMAVLink.from_json(name, frame["fields"]), what

      case frame["signature"] do
        :null ->
          assert message.signature == nil, what

        signature ->
          assert Map.delete(message.signature, :signed) == %{
                   link_id: signature["link_id"],
                   timestamp: signature["timestamp"],
                   signature: Base.decode16!(signature["signature"])
                 },
                 what

          # the signature is right for pymavlink's key, and wrong for any other
          key = Base.decode16!(signature["key"])
          assert Signing.verify(message, key), what
          refute Signing.verify(message, :crypto.hash(:sha256, key)), what
      end
    end

    kinds = frames |> Enum.map(& &1["kind"]) |> Enum.uniq() |> Enum.sort()

    assert kinds == [
             "pymavlink v1",
             "pymavlink v1 sparse",
             "pymavlink v2",
             "pymavlink v2 sparse",
             "signed v2",
             "untruncated v2"
           ]
  end

  test "frames we write parse in pymavlink with valid checksums and the same fields" do
    # every message, several times, random values over each type's range, both versions
    sent =
      for {definition, i} <- Enum.with_index(definitions()),
          round <- 1..6 do
        {:ok, {name, fields}} = :proper_gen.pick(MAVLinkGen.message(definition.name), 20 + round)
        version = if rem(round, 2) == 0, do: 1, else: 2
        header = %{system: 255, component: 190, seq: rem(i * 6 + round, 256)}
        {:ok, frame} = MAVLink.encode(name, fields, header, version)
        %{name: name, fields: fields, header: header, version: version, frame: frame}
      end

    # ArduSub's own requests, as the board will send them
    {:ok, arm} =
      MAVLink.encode(
        :command_long,
        %{
          target_system: 1,
          target_component: 1,
          command: 400,
          confirmation: 0,
          param1: 1.0,
          param2: 0.0,
          param3: 0.0,
          param4: 0.0,
          param5: 0.0,
          param6: 0.0,
          param7: 0.0
        },
        %{system: 255, component: 190, seq: 0}
      )

    path =
      Path.join(System.tmp_dir!(), "mavlink-interop-#{System.unique_integer([:positive])}.json")

    json =
      Enum.map(sent, &%{"frame" => Base.encode16(&1.frame)}) ++ [%{"frame" => Base.encode16(arm)}]

    File.write!(path, :jiffy.encode(json))

    try do
      results = PyMAVLink.run!(["decode", path])
      assert length(results) == length(sent) + 1

      for {ours, theirs} <- Enum.zip(sent, results) do
        what = "#{ours.name} v#{ours.version} #{Base.encode16(ours.frame)}: #{inspect(theirs)}"
        refute Map.has_key?(theirs, "error"), what
        assert theirs["name"] == Atom.to_string(ours.name), what
        assert theirs["version"] == ours.version, what

        assert {theirs["system"], theirs["component"], theirs["seq"]} ==
                 {ours.header.system, ours.header.component, ours.header.seq},
               what

        assert PyMAVLink.from_json(ours.name, theirs["fields"]) ==
                 MAVLinkGen.as_received(ours.name, ours.fields, ours.version),
               what
      end

      arm = List.last(results)
      assert arm["name"] == "command_long"
      assert arm["fields"]["command"] == 400 and arm["fields"]["param1"] == 1.0
    after
      File.rm(path)
    end
  end

  test "frames we sign are accepted by pymavlink with the key; with another key they are not" do
    key = Signing.key_from_passphrase("interop")
    other = Signing.key_from_passphrase("not the key")
    now = Signing.timestamp(System.os_time(:microsecond))

    signed =
      for {definition, i} <- Enum.with_index(definitions()) do
        {:ok, {name, fields}} = :proper_gen.pick(MAVLinkGen.message(definition.name), 30)
        {:ok, frame} = MAVLink.encode(name, fields, %{system: 1, component: 1, seq: 0})
        {name, fields, Signing.sign(frame, rem(i, 256), key, 2, now + i)}
      end

    path =
      Path.join(System.tmp_dir!(), "mavlink-signing-#{System.unique_integer([:positive])}.json")

    json =
      Enum.map(signed, fn {_, _, frame} ->
        %{"frame" => Base.encode16(frame), "key" => Base.encode16(key)}
      end) ++
        Enum.map(signed, fn {_, _, frame} ->
          %{"frame" => Base.encode16(frame), "key" => Base.encode16(other)}
        end)

    File.write!(path, :jiffy.encode(json))

    try do
      results = PyMAVLink.run!(["decode", path])
      {right, wrong} = Enum.split(results, length(signed))

      for {{name, fields, _frame}, theirs} <- Enum.zip(signed, right) do
        refute Map.has_key?(theirs, "error"), "#{name}: #{inspect(theirs)}"
        assert theirs["name"] == Atom.to_string(name)
        assert PyMAVLink.from_json(name, theirs["fields"]) == fields
      end

      for theirs <- wrong, do: assert(theirs["error"] =~ "signature")
    after
      File.rm(path)
    end
  end
end
