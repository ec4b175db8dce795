defmodule NeptunusWeb.HelmWireTest do
  # The helm over the wire: two and three real WebSocket clients against the running
  # endpoint, each test on its own simulated vehicle whose helm runs on an injected clock
  # (an Agent the test moves by hand; the helm never ticks on its own here).
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire

  alias Neptunus.Vehicle.Helm
  alias NeptunusWeb.Auth.{Password, Token}
  alias NeptunusWeb.Test.WSClient

  @moduletag :capture_log
  @secret String.duplicate("wire-test-secret-", 3)

  setup ctx do
    id = "helm-#{System.unique_integer([:positive])}"
    {:ok, clock} = Agent.start(fn -> 0 end)

    helm = [
      clock: fn -> Agent.get(clock, & &1) end,
      tick_ms: 3_600_000,
      request_timeout_ms: Map.get(ctx, :request_timeout_ms, 10_000),
      takeover_ms: Map.get(ctx, :takeover_ms, 3_000)
    ]

    {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: id, board: :simulated, helm: helm})

    on_exit(fn ->
      Neptunus.Fleet.stop_vehicle(id)
      Agent.stop(clock)
    end)

    {:ok, id: id, topic: "vehicle:" <> id, clock: clock}
  end

  # A client joined to the vehicle: %{ws, jr, topic, snapshot}
  defp client(ctx, params), do: client!(ctx.topic, params)

  defp local(ctx, name), do: client(ctx, %{"name" => name})

  defp push(c, event, payload \\ %{}), do: push_and_reply(c.ws, c.jr, c.topic, event, payload)

  defp pilot!(c) do
    assert {"ok", %{"status" => "granted", "grant" => %{"epoch" => epoch} = grant}} =
             push(c, "request_control")

    assert %{"pilot" => %{"id" => id}, "heartbeat_ms" => 100, "control" => %{"mode" => "motion"}} =
             grant

    assert id == c.snapshot["session"]["id"]
    assert %{"epoch" => ^epoch} = event!(c.ws, "control_granted")
    epoch
  end

  defp bob_pilots?(helm), do: match?(%{"pilot" => %{"name" => "Bob"}}, helm)

  defp telemetry_surge!(c, pred),
    do: event!(c.ws, "telemetry", &pred.(&1["command"]["surge"]))

  describe "two clients" do
    test "the second client's commands are refused and the thrust does not change", ctx do
      ada = local(ctx, "Ada")
      epoch = pilot!(ada)
      assert {"ok", %{"thrusters" => %{"port" => 0.5}}} = push(ada, "thrust", thrust(1, epoch))

      bob = local(ctx, "Bob")
      assert %{"state" => "piloted", "pilot" => %{"name" => "Ada"}} = bob.snapshot["helm"]

      for {event, payload} <- [
            {"thrust", thrust(-1, epoch)},
            {"stop", %{"reason" => "meddling"}},
            {"heartbeat", %{}},
            {"answer_request", %{"accept" => true}},
            {"release_control", %{}}
          ] do
        assert {"error", %{"reason" => "not_in_control"}} = push(bob, event, payload), event
      end

      assert {"error", %{"reason" => "forbidden"}} = push(bob, "take_control")
      telemetry_surge!(bob, &(&1 == 1.0))
      no_event!(bob.ws, "stopped", 100)

      # the pilot is marked in presence
      cy = local(ctx, "Cy")
      state = event!(cy.ws, "presence_state")
      assert [%{"pilot" => true, "role" => "pilot", "name" => "Ada"}] = state["Ada"]["metas"]
      assert [%{"pilot" => false}] = state["Bob"]["metas"]
    end

    test "request and deny: the requester is told, the pilot keeps flying", ctx do
      ada = local(ctx, "Ada")
      epoch = pilot!(ada)
      {"ok", _} = push(ada, "thrust", thrust(1, epoch))
      bob = local(ctx, "Bob")

      assert {"ok", %{"status" => "pending", "timeout_ms" => t}} = push(bob, "request_control")
      assert t in 9_000..10_000

      assert %{"from" => %{"name" => "Bob", "role" => "pilot"}} =
               event!(ada.ws, "control_request")

      assert %{"state" => "requested", "request" => %{"from" => %{"name" => "Bob"}}} =
               event!(bob.ws, "helm")

      assert {"ok", _} = push(ada, "answer_request", %{"accept" => false})
      assert %{"reason" => "denied"} = event!(bob.ws, "request_denied")
      assert %{"state" => "piloted", "request" => nil} = event!(bob.ws, "helm")
      telemetry_surge!(bob, &(&1 == 1.0))

      assert {"error", %{"reason" => "no_request"}} =
               push(ada, "answer_request", %{"accept" => true})

      assert {"error", %{"reason" => "accept must be true or false"}} =
               push(ada, "answer_request", %{"accept" => "yes"})
    end

    @tag request_timeout_ms: 150
    test "an unanswered request times out", ctx do
      ada = local(ctx, "Ada")
      pilot!(ada)
      bob = local(ctx, "Bob")
      assert {"ok", %{"status" => "pending"}} = push(bob, "request_control")

      assert %{"reason" => "request_timeout"} = event!(bob.ws, "request_denied", fn _ -> true end)

      assert %{"state" => "piloted", "pilot" => %{"name" => "Ada"}} =
               event!(ada.ws, "helm", &(&1["request"] == nil))
    end

    test "the pilot's disconnect stops the vehicle and frees the helm", ctx do
      ada = local(ctx, "Ada")
      epoch = pilot!(ada)
      {"ok", _} = push(ada, "thrust", thrust(1, epoch))
      bob = local(ctx, "Bob")
      telemetry_surge!(bob, &(&1 == 1.0))

      WSClient.close(ada.ws)

      assert %{"reason" => "pilot_disconnected"} = event!(bob.ws, "stopped")
      assert %{"state" => "free", "pilot" => nil} = event!(bob.ws, "helm")
      assert %{"thrusters" => %{"port" => +0.0}} = telemetry_surge!(bob, &(&1 == 0.0))
      # the free helm is granted at once
      pilot!(bob)
    end

    test "the pilot leaving the topic stops the vehicle", ctx do
      ada = local(ctx, "Ada")
      pilot!(ada)
      bob = local(ctx, "Bob")
      assert {"ok", _} = push(ada, "phx_leave")
      assert %{"reason" => "pilot_left"} = event!(bob.ws, "stopped")
    end

    test "blur: the pilot's stop with a reason reaches everyone", ctx do
      ada = local(ctx, "Ada")
      epoch = pilot!(ada)
      {"ok", _} = push(ada, "thrust", thrust(1, epoch))
      bob = local(ctx, "Bob")

      assert {"ok", %{"thrusters" => %{"port" => +0.0}}} =
               push(ada, "stop", %{"reason" => "window_blur"})

      assert %{"reason" => "window_blur"} = event!(bob.ws, "stopped")
      # the pilot keeps the helm, and the same epoch moves the vehicle again
      assert {"ok", _} = push(ada, "thrust", thrust(0.5, epoch))
    end

    test "a pilot whose channel crashes gives the helm up (phx_error, vehicle stopped)", ctx do
      ada = local(ctx, "Ada")
      epoch = pilot!(ada)
      {"ok", _} = push(ada, "thrust", thrust(1, epoch))
      # the pilot's connection is served first (Neptunus.PubSub.prioritize/2)
      [socket_pid] = :pg.get_members(Neptunus.PubSub, {:fastlane_first, ctx.topic})
      bob = local(ctx, "Bob")

      # a message the channel has no clause for: it raises inside the connection process
      send(socket_pid, {:channel_info, ctx.topic, :unexpected})

      assert [_, _, _, "phx_error", _] =
               WSClient.recv_until(ada.ws, &match?([_, _, _, "phx_error", _], &1))

      assert %{"reason" => "pilot_disconnected"} = event!(bob.ws, "stopped")
      assert %{"state" => "free"} = event!(bob.ws, "helm")
      telemetry_surge!(bob, &(&1 == 0.0))
    end

    test "release: stop, free helm", ctx do
      ada = local(ctx, "Ada")
      pilot!(ada)
      bob = local(ctx, "Bob")
      assert {"ok", %{"helm" => %{"state" => "free"}}} = push(ada, "release_control")
      assert %{"reason" => "released"} = event!(ada.ws, "control_lost")
      assert %{"reason" => "released"} = event!(bob.ws, "stopped")
    end
  end

  describe "three clients" do
    test "request and accept: neutral on transfer, old pilot refused, stale stamps refused",
         ctx do
      ada = local(ctx, "Ada")
      epoch = pilot!(ada)
      {"ok", _} = push(ada, "thrust", thrust(1, epoch))
      bob = local(ctx, "Bob")
      cy = local(ctx, "Cy")

      # Bob stamps with the epoch he saw in his snapshot: not his (he is not in control)
      assert bob.snapshot["helm"]["epoch"] == epoch
      assert {"error", %{"reason" => "not_in_control"}} = push(bob, "thrust", thrust(-1, epoch))

      assert {"ok", %{"status" => "pending"}} = push(bob, "request_control")
      assert {"error", %{"reason" => "busy"}} = push(cy, "request_control")
      assert %{"from" => %{"name" => "Bob"}} = event!(ada.ws, "control_request")

      assert {"ok", _} = push(ada, "answer_request", %{"accept" => true})

      assert %{
               "stopped" => %{"reason" => "control_transferred"},
               "control_lost" => %{"reason" => "control_transferred"},
               "helm" => %{"state" => "piloted", "pilot" => %{"name" => "Bob"}}
             } = collect!(ada.ws, ["stopped", "control_lost", {"helm", &bob_pilots?/1}])

      assert %{
               "stopped" => %{"reason" => "control_transferred"},
               "control_granted" => %{"epoch" => new_epoch, "control" => control},
               "helm" => %{"pilot" => %{"name" => "Bob"}}
             } = collect!(bob.ws, ["stopped", "control_granted", {"helm", &bob_pilots?/1}])

      assert %{"stopped" => _, "helm" => %{"pilot" => %{"name" => "Bob"}}} =
               collect!(cy.ws, ["stopped", {"helm", &bob_pilots?/1}])

      assert new_epoch == epoch + 1
      # pick-up: the new pilot gets the control state, neutral
      assert %{"command" => %{"surge" => +0.0}, "mode" => "motion", "gain" => 0.5} = control
      telemetry_surge!(cy, &(&1 == 0.0))

      assert {"error", %{"reason" => "not_in_control"}} = push(ada, "thrust", thrust(1, epoch))
      # a command Bob made before he heard of his grant is stale; unstamped is refused too
      assert {"error", %{"reason" => "stale_command"}} = push(bob, "thrust", thrust(-1, epoch))
      assert {"error", %{"reason" => "missing field: epoch"}} = push(bob, "thrust", thrust(-1))
      telemetry_surge!(cy, &(&1 == 0.0))

      assert {"ok", _} = push(bob, "thrust", thrust(-1, new_epoch))
      telemetry_surge!(cy, &(&1 == -1.0))

      # presence: the pilot mark moved from Ada to Bob
      state = event!(local(ctx, "Dee").ws, "presence_state")
      assert [%{"pilot" => true}] = state["Bob"]["metas"]
      assert [%{"pilot" => false}] = state["Ada"]["metas"]
    end

    test "deadman with an injected clock: only the pilot's heartbeats count", ctx do
      ada = local(ctx, "Ada")
      epoch = pilot!(ada)
      {"ok", _} = push(ada, "thrust", thrust(1, epoch))
      bob = local(ctx, "Bob")
      cy = local(ctx, "Cy")

      # the pilot's heartbeats every 100 ms keep the vehicle going
      for _ <- 1..10 do
        Agent.update(ctx.clock, &(&1 + 100))
        assert {"ok", %{}} = push(ada, "heartbeat")
        :ok = Helm.check_deadman(ctx.id)
      end

      no_event!(cy.ws, "stopped", 50)

      # the pilot goes silent; a helper's heartbeats do not count
      for _ <- 1..5 do
        Agent.update(ctx.clock, &(&1 + 100))
        assert {"error", %{"reason" => "not_in_control"}} = push(bob, "heartbeat")
        :ok = Helm.check_deadman(ctx.id)
      end

      Agent.update(ctx.clock, &(&1 + 1))
      :ok = Helm.check_deadman(ctx.id)

      tripped = epoch + 1

      for c <- [ada, bob, cy] do
        assert %{"reason" => "deadman"} = event!(c.ws, "stopped")
        assert %{"state" => "piloted", "epoch" => ^tripped} = event!(c.ws, "helm")
      end

      telemetry_surge!(cy, &(&1 == 0.0))

      # thrust stays neutral: heartbeats don't bring it back, the pre-trip stamp is stale
      assert {"ok", _} = push(ada, "heartbeat")
      assert {"error", %{"reason" => "stale_command"}} = push(ada, "thrust", thrust(1, epoch))
      telemetry_surge!(cy, &(&1 == 0.0))
      assert {"ok", _} = push(ada, "thrust", thrust(0.5, tripped))
      telemetry_surge!(cy, &(&1 == 0.5))
    end
  end

  describe "roles (secure mode)" do
    setup do
      hash = Password.hash("pw", iterations: 1000)

      users =
        for {name, role} <- [{"ada", :pilot}, {"main", :main_station}, {"olga", :observer}],
            into: %{},
            do: {name, %{name: name, role: role, hash: hash}}

      NeptunusWeb.Test.Wire.settings!(
        auth: %{
          mode: :secure,
          secret: @secret,
          users: users,
          anonymous_observers: false,
          origins: []
        }
      )
    end

    defp as(ctx, user) do
      client(ctx, %{"token" => Token.sign(user, @secret, System.os_time(:second), 600)})
    end

    @tag takeover_ms: 300
    test "main-station takeover with a warning countdown; observers only watch", ctx do
      ada = as(ctx, "ada")
      assert %{"name" => "ada", "role" => "pilot", "mode" => "secure"} = ada.snapshot["session"]
      epoch = pilot!(ada)
      {"ok", _} = push(ada, "thrust", thrust(1, epoch))
      main = as(ctx, "main")
      olga = as(ctx, "olga")

      assert {"error", %{"reason" => "forbidden"}} = push(olga, "request_control")
      assert {"error", %{"reason" => "forbidden"}} = push(olga, "take_control")
      assert {"error", %{"reason" => "not_in_control"}} = push(olga, "thrust", thrust(-1, epoch))
      assert {"error", %{"reason" => "forbidden"}} = push(ada, "take_control")

      assert {"ok", %{"status" => "takeover", "countdown_ms" => ms}} = push(main, "take_control")
      assert ms in 1..300

      # the warning reaches both parties (and everyone else) before the transfer
      for c <- [ada, main, olga] do
        assert %{
                 "state" => "takeover",
                 "pilot" => %{"name" => "ada"},
                 "takeover" => %{
                   "by" => %{"name" => "main", "role" => "main_station"},
                   "countdown_ms" => _
                 }
               } = event!(c.ws, "helm", &(&1["state"] == "takeover"))
      end

      # the pilot still flies during the countdown
      assert {"ok", _} = push(ada, "thrust", thrust(0.5, epoch))

      assert %{"epoch" => new_epoch} = event!(main.ws, "control_granted", fn _ -> true end)

      assert new_epoch == epoch + 1
      assert %{"reason" => "main_station_takeover"} = event!(ada.ws, "control_lost")

      assert %{
               "stopped" => %{"reason" => "main_station_takeover"},
               "helm" => %{"pilot" => %{"name" => "main", "role" => "main_station"}}
             } = collect!(olga.ws, ["stopped", {"helm", &(&1["pilot"]["name"] == "main")}])

      telemetry_surge!(olga, &(&1 == 0.0))
      assert {"error", %{"reason" => "not_in_control"}} = push(ada, "thrust", thrust(1, epoch))
      assert {"ok", _} = push(main, "thrust", thrust(0.2, new_epoch))
    end
  end
end
