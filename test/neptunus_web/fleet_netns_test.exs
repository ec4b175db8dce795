defmodule NeptunusWeb.FleetNetnsTest do
  @moduledoc """
  A partition by cutting a network link (root and `ip netns` needed; skipped, saying why,
  elsewhere): a vehicle node V and a topside node T, each in its own network namespace,
  joined by a veth pair, talking distribution over TLS (`inet_tls_dist`, a throwaway CA and
  certificate made here) under their real configuration (`Neptunus.Config.Cluster`: off
  loopback, TLS is required), with a short `net_ticktime`. Both are controlled from the
  test node over their standard input/output (`Neptunus.Test.Cluster.start_peer!/5`),
  which the cut does not touch. A pilot connected to T drives the vehicle on V; the link is
  set down: V stops the vehicle (deadman, or the pilot's node lost), T says unreachable and
  that its pilot lost control; the link is set up: T's connector reconnects, and nobody is in
  control until a fresh `request_control`.
  """
  use ExUnit.Case, async: false

  alias Neptunus.Test.Cluster
  alias Neptunus.Test.Cluster.{Collector, Netns, Pilot}

  @moduletag timeout: 120_000
  @moduletag :netns

  case Netns.unavailable() do
    nil ->
      :ok

    why ->
      IO.puts(:stderr, "FleetNetnsTest skipped: needs root and `ip netns` (#{why})")
      @moduletag skip: "needs root and `ip netns`: #{why}"
  end

  defp port, do: Application.fetch_env!(:neptunus, :endpoint).port

  setup do
    n = System.unique_integer([:positive])
    prefix = "nx#{rem(port(), 10_000)}#{rem(n, 100)}"
    pair = Netns.setup!(prefix, {213, rem(port() + n, 250)})
    dir = Path.join(System.tmp_dir!(), "neptunus_netns_#{prefix}")

    # (on_exit callbacks run last first: the peers stop before this)
    on_exit(fn ->
      Netns.cleanup(pair)
      File.rm_rf(dir)
    end)

    {:ok, pair: pair, dir: dir}
  end

  defp start_in_ns!(ctx, ns, name, http_port, vehicles, cluster_env) do
    cluster = Neptunus.Config.Cluster.cluster!(cluster_env)
    %{tls: tls} = cluster
    optfile = Path.join(ctx.dir, "#{name}.ssl_dist")
    File.write!(optfile, Neptunus.Config.Cluster.ssl_dist_optfile(tls))
    [_, host] = cluster.node |> Atom.to_string() |> String.split("@")

    peer =
      Cluster.start_peer!(name, http_port, vehicles, [cluster: cluster],
        host: host,
        cookie: cluster.cookie,
        exec: Netns.erl_in(ns),
        args: ~w(-proto_dist inet_tls -ssl_dist_optfile #{optfile} -kernel net_ticktime 2)
      )

    on_exit(fn -> Cluster.stop_peer(peer) end)
    peer
  end

  defp events(peer, pid, module), do: Cluster.call(peer, module, :events, [pid])

  test "cutting the link: V stops the vehicle, T says unreachable; after healing a fresh request picks up",
       ctx do
    %{ns: {ns_v, ns_t}, addrs: {addr_v, addr_t}} = ctx.pair
    tls = Netns.certificates!(ctx.dir, [addr_v, addr_t])
    cookie = Base.encode64(:crypto.strong_rand_bytes(30))

    env = %{
      "NEPTUNUS_COOKIE" => cookie,
      "NEPTUNUS_DIST_CERT" => tls.certfile,
      "NEPTUNUS_DIST_KEY" => tls.keyfile,
      "NEPTUNUS_DIST_CACERT" => tls.cacertfile
    }

    # off loopback without TLS files, a node refuses to start distributed
    assert_raise ArgumentError, ~r/NEPTUNUS_DIST_CERT/, fn ->
      Neptunus.Config.Cluster.cluster!(%{
        "NEPTUNUS_NODE" => "v@#{addr_v}",
        "NEPTUNUS_COOKIE" => cookie
      })
    end

    id = "ns-rov-#{System.unique_integer([:positive])}"
    topic = "vehicle:" <> id
    v_node = "v@#{addr_v}"

    v =
      start_in_ns!(
        ctx,
        ns_v,
        :v,
        port() + 6,
        [%{id: id, board: :simulated}],
        Map.put(env, "NEPTUNUS_NODE", v_node)
      )

    t =
      start_in_ns!(
        ctx,
        ns_t,
        :t,
        port() + 7,
        [],
        Map.merge(env, %{"NEPTUNUS_NODE" => "t@#{addr_t}", "NEPTUNUS_CLUSTER" => v_node})
      )

    # T's connector joins V over the veth, over TLS
    v_atom = String.to_atom(v_node)

    Cluster.wait!(
      fn -> match?({:ok, ^v_atom, _}, Cluster.call(t, Neptunus.Fleet, :locate, [id])) end,
      "#{id} located on #{v_node} from T",
      15_000
    )

    assert Cluster.call(t, :net_kernel, :get_net_ticktime, []) == 2
    assert {:ok, [[~c"inet_tls"]]} = Cluster.call(v, :init, :get_argument, [:proto_dist])

    {:ok, collector} = Cluster.call(v, Collector, :start, [topic])
    {:ok, pilot} = Cluster.call(t, Pilot, :start, [t.port, topic, "Ada"])

    assert {"ok", %{"status" => "granted", "grant" => %{"epoch" => epoch}}} =
             Cluster.call(t, Pilot, :push, [pilot, "request_control", %{}])

    :ok = Cluster.call(t, Pilot, :drive, [pilot, epoch])

    # the pilot on T drives the vehicle on V
    Cluster.wait!(
      fn ->
        match?(
          %{command: %{surge: s}} when s > 0,
          Cluster.call(v, Neptunus.Vehicle.Telemetry, :latest, [id])
        )
      end,
      "the pilot's thrust on V"
    )

    Netns.cut!(ctx.pair, :a)

    # V: neutral, and why: the deadman (no more heartbeats) or the pilot's node lost,
    # whichever comes first (the event, not its timing)
    Cluster.wait!(
      fn ->
        Enum.any?(events(v, collector, Collector), fn
          {"stopped", %{reason: reason}} -> reason in ["deadman", "pilot_unreachable"]
          _ -> false
        end)
      end,
      "V stops the vehicle"
    )

    # once the nodes have seen each other go (net_ticktime): V freed the helm, T says
    # unreachable and that its pilot lost control
    Cluster.wait!(
      fn -> match?(%{pilot: nil}, Cluster.call(v, Neptunus.Vehicle.Helm, :status, [id])) end,
      "V frees the helm",
      15_000
    )

    Cluster.wait!(
      fn ->
        seen = events(t, pilot, Pilot)

        Enum.any?(
          seen,
          &match?({"unreachable", %{"id" => ^id, "reason" => "node_unreachable"}}, &1)
        ) and
          Enum.any?(seen, &match?({"control_lost", %{"reason" => "pilot_unreachable"}}, &1))
      end,
      "T says unreachable, and that its pilot lost control",
      15_000
    )

    assert {:error, :unreachable} = Cluster.call(t, Neptunus.Fleet, :locate, [id])

    assert %{command: command} = Cluster.call(v, Neptunus.Vehicle.Telemetry, :latest, [id])

    assert Enum.all?(Map.take(command, [:surge, :sway, :heave, :yaw]), fn {_, s} ->
             s in [0, 0.0, nil]
           end)

    :ok = Cluster.call(t, Pilot, :drive, [pilot, nil])
    Netns.heal!(ctx.pair, :a)

    # T's connector reconnects (with backoff)
    Cluster.wait!(
      fn -> Enum.any?(events(t, pilot, Pilot), &match?({"reachable", %{"id" => ^id}}, &1)) end,
      "T sees V again",
      20_000
    )

    # nobody in control after healing: the old grant is void, a fresh request picks up
    assert {"error", %{"reason" => "not_in_control"}} =
             Cluster.call(t, Pilot, :push, [
               pilot,
               "thrust",
               %{"mode" => "motion", "surge" => 0.5, "heave" => 0, "yaw" => 0, "epoch" => epoch}
             ])

    assert {"ok", %{"status" => "granted"}} =
             Cluster.call(t, Pilot, :push, [pilot, "request_control", %{}])
  end
end
