defmodule NeptunusWeb.WireSchemaTest do
  # The wire schema (NeptunusWeb.WireSchema) is whole, its committed copies — the TypeScript
  # types and decoders, the tables of docs/API.md — are what it gives, and the JS fake server
  # speaks it. (The server's own payloads: wire_conformance_test.exs.)
  use ExUnit.Case, async: true

  alias NeptunusWeb.Test.Conformance
  alias NeptunusWeb.WireSchema
  alias NeptunusWeb.WireSchema.{Check, Derived, Docs}

  doctest NeptunusWeb.WireSchema.Check

  @root Path.expand("../..", __DIR__)

  defp names_in(type) do
    case type do
      t when t in [:number, :integer, :string, :boolean] -> []
      {:enum, _} -> []
      {kind, inner} when kind in [:list, :map, :or_null] -> names_in(inner)
      {:one_of, types} -> Enum.flat_map(types, &names_in/1)
      name when is_atom(name) -> [name]
    end
  end

  test "every type named in the schema is defined, once; every message once per topic" do
    definitions = WireSchema.definitions()
    defined = Enum.map(definitions, & &1.name)
    assert defined -- Enum.uniq(defined) == []

    used =
      Enum.flat_map(definitions, fn
        %{kind: :object, fields: fields} -> Enum.flat_map(fields, &names_in(&1.type))
        %{kind: :union, types: types} -> Enum.flat_map(types, &names_in/1)
        %{kind: :enum} -> []
      end) ++
        Enum.flat_map(WireSchema.events() ++ WireSchema.joins(), &names_in(&1.payload)) ++
        Enum.flat_map(WireSchema.commands(), &(names_in(&1.payload) ++ names_in(&1.reply)))

    assert Enum.uniq(used) -- defined == []
    # and nothing is defined that no message uses
    assert defined -- used == []

    for messages <- [WireSchema.events(), WireSchema.commands()] do
      keys = Enum.map(messages, &{&1.topic, &1.name})
      assert keys -- Enum.uniq(keys) == []
    end

    for field <- Enum.flat_map(definitions, &Map.get(&1, :fields, [])),
        field.type in [:number, :integer] and field.unit != nil do
      assert field.unit in [
               "m",
               "m/s",
               "rad",
               "rad/s",
               "V",
               "A",
               "s",
               "ms",
               "µs",
               "°",
               "ms since the epoch"
             ],
             "#{field.name}: unit #{field.unit}"
    end
  end

  test "the committed TypeScript and the docs' tables are what the schema gives" do
    for {path, text} <- Derived.files(@root) do
      assert File.read!(Path.join(@root, path)) == text,
             "#{path} is out of date: run `mix neptunus.gen.wire` and commit what it writes"
    end
  end

  test "the docs' sections are all there, and a section whose markers are broken is refused" do
    text = File.read!(Path.join(@root, Docs.path()))

    for name <- Docs.sections() do
      assert text =~ "<!-- wire:begin #{name} -->\n"
      assert text =~ "<!-- wire:end #{name} -->"
    end

    assert_raise ArgumentError, ~r/wire:end payloads/, fn ->
      Docs.update(String.replace(text, "<!-- wire:end payloads -->", ""))
    end
  end

  test "the check: what the server may send, and what a page needs" do
    link = %{"up" => true, "reason" => "open"}
    assert :ok = Check.check(:link_status, link)
    assert {:error, ["reason: null"]} = Check.check(:link_status, %{link | "reason" => nil})
    assert {:error, ["reason: missing"]} = Check.check(:link_status, Map.delete(link, "reason"))
    assert :ok = Check.check(:link_status, Map.delete(link, "reason"), decodable: true)
    assert {:error, ["up: missing"]} = Check.check(:link_status, %{}, decodable: true)

    assert {:error,
            ["mavlink.armed: expected boolean, got \"yes\"", "mavlink.x: not in the schema"]} =
             Check.check(:link_status, Map.put(link, "mavlink", %{"armed" => "yes", "x" => 1}),
               decodable: true
             )

    assert {:error, ["[1]: expected number, got \"a\""]} = Check.check({:list, :number}, [1, "a"])
    assert :ok = Check.check({:list, {:or_null, :number}}, [1, nil])
    assert :ok = Check.check(:pilot_command, %{"port" => 0, "vertical" => 0, "starboard" => 0})
    assert {:error, [_]} = Check.check(:pilot_command, %{"port" => 0})

    assert :ok =
             Check.check_term(:camera_status, %{
               running: true,
               fps: 15,
               error: nil,
               state: "running",
               restarts: 0,
               codec: "mjpeg",
               width: 640,
               height: 480
             })
  end

  @tag :external
  test "the JS fake server (assets/test/support/fake_server.mjs) speaks the schema, in a page's terms" do
    node = System.find_executable("node") || flunk("node is not installed: run `make setup`")

    {output, status} =
      System.cmd(node, ["test/support/fake_server_sample.mjs"], cd: Path.join(@root, "assets"))

    assert status == 0, output
    {:ok, frames} = Neptunus.JSON.decode(output)
    assert length(frames) > 20

    for %{"pushed" => pushed, "frame" => frame} <- frames do
      Conformance.conform_frame!(frame, pushed, decodable: true)
    end

    seen = Conformance.seen() |> Enum.map(fn {_, _, name} -> name end) |> MapSet.new()

    for name <- ~w(phx_join telemetry helm presence_state presence_diff control_granted
                   control_request control_lost request_denied stopped log thrust stop set_gain
                   heartbeat request_control answer_request release_control) do
      assert name in seen, "the fake server sample has no #{name}"
    end
  end
end
