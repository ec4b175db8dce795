defmodule Neptunus.Protocol.MAVLinkInteropTest do
  # Our codec against pymavlink (the reference Python implementation, from PyPI, pinned in the
  # Makefile and installed by `make setup` into .venv/): the definitions agree, pymavlink's
  # frames decode to the same fields here, and our frames parse in pymavlink with valid
  # checksums and the same fields.
  use ExUnit.Case, async: true

  @moduletag :external
  @moduletag timeout: 120_000

  alias Neptunus.Protocol.MAVLink
  alias Neptunus.Protocol.MAVLink.Messages
  alias Neptunus.Test.MAVLinkGen
  alias Neptunus.Test.PyMAVLink

  defp names, do: Enum.map(Messages.all(), &Atom.to_string(&1.name))

  test "every definition agrees with pymavlink's: id, CRC_EXTRA, fields, wire order, arrays" do
    info = PyMAVLink.run!(["info" | names()])

    for definition <- Messages.all() do
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
    assert length(frames) == 6 * length(Messages.all())

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
          assert message.signature == %{
                   link_id: signature["link_id"],
                   timestamp: signature["timestamp"],
                   signature: Base.decode16!(signature["signature"])
                 },
                 what
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
      for {definition, i} <- Enum.with_index(Messages.all()),
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
end
