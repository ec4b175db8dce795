defmodule Neptunus.Vehicle.HelmEpochTest do
  # Command stamps never repeat within the node's life: not after a helm crash, not after
  # a restart of the vehicle's whole tree.
  use ExUnit.Case, async: true

  alias Neptunus.{Fleet, PubSub}
  alias Neptunus.Helm.Policy
  alias Neptunus.Vehicle.{Helm, Telemetry}

  @moduletag :capture_log

  setup do
    id = "epoch-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Telemetry.topic(id))
    start_supervised!(vehicle(id), id: :vehicle)
    assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}
    {:ok, id: id}
  end

  defp vehicle(id), do: {Neptunus.Vehicle.Supervisor, %{id: id, board: :simulated}}

  defp party(name) do
    test = self()
    pid = spawn(fn -> receive do: (:die -> :ok) end)

    %{
      id: "#{name}-#{System.unique_integer([:positive])}",
      name: name,
      role: :pilot,
      pid: pid,
      notify: fn event, payload -> send(test, {:notify, name, event, payload}) end
    }
  end

  defp pilot!(id, party) do
    assert {:ok, %{status: "granted", grant: %{epoch: epoch}}} = Helm.request_control(id, party)
    epoch
  end

  defp thrust(id, party, epoch) do
    payload = %{"mode" => "motion", "surge" => 0.5, "heave" => 0, "yaw" => 0, "epoch" => epoch}
    Helm.thrust(id, party, payload)
  end

  test "after a helm crash a thrust stamped before it is stale", %{id: id} do
    ada = party("ada")
    old = pilot!(id, ada)
    assert {:ok, _} = thrust(id, ada, old)

    helm = GenServer.whereis(Fleet.via(Helm, id))
    Process.exit(helm, :kill)
    assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}
    refute GenServer.whereis(Fleet.via(Helm, id)) in [nil, helm]

    # the same client takes the helm again; its buffered pre-crash thrust must not run
    new = pilot!(id, ada)
    assert {:error, "stale_command"} = thrust(id, ada, old)
    assert new > old
    assert {:ok, _} = thrust(id, ada, new)
  end

  test "after a restart of the vehicle's tree a thrust stamped before it is stale", %{id: id} do
    ada = party("ada")
    old = pilot!(id, ada)
    assert {:ok, _} = thrust(id, ada, old)

    stop_supervised!(:vehicle)
    start_supervised!(vehicle(id), id: :vehicle)
    assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}

    new = pilot!(id, ada)
    assert {:error, "stale_command"} = thrust(id, ada, old)
    assert new > old
  end

  test "epochs are JSON-safe integers" do
    epoch = Helm.first_epoch()
    assert is_integer(epoch) and epoch >= 0 and epoch < Integer.pow(2, 53)
  end

  test "a policy counts from the epoch it starts at" do
    p = %{id: "a", name: "a", role: :pilot, pid: self(), notify: nil}
    {{:ok, :granted}, s, _} = Policy.handle(Policy.new(41), {:request, p}, 0)
    assert s.epoch == 42
    assert Policy.new().epoch == 0
  end
end
