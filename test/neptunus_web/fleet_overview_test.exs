defmodule NeptunusWeb.FleetOverviewTest do
  # The fleet channel's live feed (`Neptunus.Fleet.Overview`) through a real WebSocket.
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire

  alias Neptunus.Fleet.Overview

  @moduletag :capture_log

  test "a page on topic fleet gets the directory as it changes: a vehicle started later, its pilot" do
    ws = connect!(%{name: "overview"})
    {_jr, %{"vehicles" => before}} = join!(ws, "fleet")
    %{id: id, topic: topic} = start_vehicle!("overview")
    refute Enum.any?(before, &(&1["id"] == id))

    :ok = Overview.refresh()

    listed =
      event!(ws, "vehicles", fn %{"vehicles" => vs} -> Enum.any?(vs, &(&1["id"] == id)) end)

    node = Atom.to_string(node())

    assert %{"node" => ^node, "status" => "up", "pilot" => nil, "recording" => false} =
             Enum.find(listed["vehicles"], &(&1["id"] == id))

    # a pilot takes it: the next read says who
    pilot = connect!(%{name: "ada"})
    {jr, _} = join!(pilot, topic)
    assert {"ok", _} = push_and_reply(pilot, jr, topic, "request_control", %{})
    :ok = Overview.refresh()

    event!(ws, "vehicles", fn %{"vehicles" => vs} ->
      match?(%{"pilot" => "ada", "helm" => _}, Enum.find(vs, &(&1["id"] == id)))
    end)
  end

  test "nothing is read or sent while no page is on topic fleet" do
    ws = connect!(%{name: "other"})
    {_jr, _} = join!(ws, "vehicle:neptunus-1")
    :ok = Overview.refresh()
    no_event!(ws, "vehicles", 200)
    assert %{last: nil} = :sys.get_state(Overview)
  end
end
