defmodule Neptunus.GCS.SessionTest do
  use ExUnit.Case, async: true

  import Neptunus.Test.Properties

  alias Neptunus.GCS.{Party, Session}
  alias Neptunus.Protocol.MAVLink
  alias Neptunus.Protocol.MAVLink.Message
  alias Neptunus.Test.GCSClient
  alias Neptunus.Test.MAVLinkGen, as: Gen

  @pilot %{name: "qgc", role: :pilot, trusted: false}
  @observer %{name: "olga", role: :observer, trusted: false}
  @main %{name: "topside", role: :main_station, trusted: false}
  @trusted %{name: "gcs-255", role: :pilot, trusted: true}

  # MAV_RESULT
  @accepted 0
  @temporarily_rejected 1
  @denied 2
  @unsupported 3
  @failed 4
  @in_progress 5

  defp session(identity, board \\ :simulated) do
    Session.new("udpin0/127.0.0.1:5000", identity, %{1 => %{id: "rov", board: board}}, 0)
  end

  defp msg(name, fields, system \\ 255) do
    {:ok, frame} = MAVLink.encode(name, fields, %{system: system, component: 190, seq: 0})
    {_, [message], []} = MAVLink.decode(MAVLink.new(), frame)
    message
  end

  defp heartbeat,
    do: msg(:heartbeat, %{type: 6, autopilot: 8, base_mode: 0, custom_mode: 0, system_status: 4})

  defp manual(x, z \\ 500, r \\ 0, target \\ 1),
    do: msg(:manual_control, %{target: target, x: x, y: 0, z: z, r: r, buttons: 0})

  defp command(command, params, target \\ 1),
    do: msg(:command_long, GCSClient.command_long(target, command, params))

  defp handle(s, event), do: Session.handle(s, event)
  defp receive_msg(s, message, now \\ 0), do: handle(s, {:message, message, now})

  # a session that has spoken (its ground station is known) and, if asked, pilots
  defp spoken(identity \\ @pilot, board \\ :simulated) do
    {s, _} = receive_msg(session(identity, board), heartbeat())
    s
  end

  defp piloting(identity \\ @pilot, board \\ :simulated, epoch \\ 7) do
    s = spoken(identity, board)

    {s, _} =
      handle(
        s,
        {:vehicle, 1, view(%{pilot: %{id: Session.party_id(s), name: "me"}, epoch: epoch})}
      )

    s
  end

  defp view(helm, control \\ %{mode: "motion", autopilot: %{depth: nil, heading: nil}}) do
    %{
      helm:
        Map.merge(
          %{
            state: if(helm[:pilot], do: "piloted", else: "free"),
            epoch: 1,
            pilot: nil,
            request_timeout_ms: 10_000
          },
          helm
        ),
      control: control,
      board: :simulated
    }
  end

  defp acks(actions), do: for({:send, 1, :command_ack, f} <- actions, do: {f.command, f.result})
  defp texts(actions), do: for({:text, 1, _severity, text} <- actions, do: text)
  defp intents(actions), do: for({:intent, _ref, 1, intent} <- actions, do: intent)

  defp ref_of(actions),
    do:
      Enum.find_value(actions, fn
        {:intent, ref, _, _} -> ref
        _ -> nil
      end)

  describe "who it is" do
    test "the first message names the ground station; another system on the session is ignored" do
      s = spoken()
      assert s.gcs == {255, 190}
      assert Session.party_id(s) == Party.id(255, "udpin0/127.0.0.1:5000")
      assert Session.party_name(s) == "qgc (GCS 255)"

      {s, actions} =
        receive_msg(
          s,
          msg(
            :heartbeat,
            %{type: 6, autopilot: 8, base_mode: 0, custom_mode: 0, system_status: 4},
            254
          )
        )

      assert actions == []
      assert s.counters.foreign == 1
    end

    test "its helm party's id carries its system id" do
      assert Party.sysid(Session.party_id(spoken())) == 255
    end

    test "the vehicle's helm says whether it pilots, and its epoch" do
      s = piloting(@pilot, :simulated, 42)
      assert Session.piloting(s) == [1]
      assert s.vehicles[1].epoch == 42

      # the helm went to someone else (a grant: a newer epoch)
      {s, []} = handle(s, {:vehicle, 1, view(%{pilot: %{id: "someone else"}, epoch: 43})})
      assert Session.piloting(s) == []
    end

    test "a silent session ends; one that speaks goes on" do
      s = spoken()
      assert {_, []} = handle(s, {:check, 4_000})
      assert {_, [:close]} = handle(s, {:check, 5_001})
      {s, _} = receive_msg(s, heartbeat(), 5_000)
      assert {_, []} = handle(s, {:check, 9_000})
    end
  end

  describe "the sticks" do
    test "MANUAL_CONTROL from the pilot is a thrust stamped with the epoch, once per change; repeats only feed the deadman" do
      s = piloting()
      {s, actions} = receive_msg(s, manual(500, 250, -1000))
      assert [{:thrust, %{surge: 0.5, heave: 0.5, yaw: -1.0}, 7}] = intents(actions)

      {s, actions} = receive_msg(s, manual(500, 250, -1000))
      assert intents(actions) == [:heartbeat]

      {_s, actions} = receive_msg(s, manual(0))
      assert [{:thrust, %{surge: 0.0, heave: 0.0, yaw: 0.0}, 7}] = intents(actions)
    end

    test "from anyone but the pilot it is ignored and counted" do
      s = spoken()
      {s, actions} = receive_msg(s, manual(500))
      assert actions == []
      {s, actions} = receive_msg(s, manual(500, 500, 0, 9))
      assert actions == []
      {s, actions} = receive_msg(s, manual(500, 500, 0, 0))
      assert actions == []
      assert s.counters.manual_ignored == 3
    end

    test "RC_CHANNELS_OVERRIDE is a stick too (ArduSub's channels)" do
      s = piloting()

      channels =
        for i <- 1..18,
            into: %{target_system: 1, target_component: 1},
            do: {:"chan#{i}_raw", 1500}

      {_s, actions} = receive_msg(s, msg(:rc_channels_override, %{channels | chan5_raw: 1900}))
      assert [{:thrust, %{surge: 1.0, heave: +0.0, yaw: +0.0}, 7}] = intents(actions)
    end

    test "a stale stamp: the epoch is read again and the next input goes" do
      s = piloting()
      {s, actions} = receive_msg(s, manual(500))
      ref = ref_of(actions)
      {s, actions} = handle(s, {:result, ref, {:error, "stale_command"}})
      assert [:status] = intents(actions)
      {s, []} = handle(s, {:result, ref_of(actions), {:ok, %{epoch: 8}}})
      {_s, actions} = receive_msg(s, manual(500))
      assert [{:thrust, %{surge: 0.5}, 8}] = intents(actions)
    end

    test "the ground station's HEARTBEAT feeds the deadman of the helms it holds" do
      assert {_, []} = receive_msg(spoken(), heartbeat())
      assert {_, [{:intent, 0, 1, :heartbeat}]} = receive_msg(piloting(), heartbeat())
    end

    test "a trusted ground station takes a free helm with its stick; its next input flies" do
      {s, _} = receive_msg(session(@trusted), heartbeat())
      {s, []} = handle(s, {:vehicle, 1, view(%{})})
      {s, actions} = receive_msg(s, manual(500))
      assert [:request_control] = intents(actions)
      # no second request while the first is out
      {s, []} = receive_msg(s, manual(500))

      {s, []} =
        handle(s, {:result, ref_of(actions), {:ok, %{status: "granted", grant: %{epoch: 3}}}})

      {_s, actions} = receive_msg(s, manual(500))
      assert [{:thrust, %{surge: 0.5}, 3}] = intents(actions)
    end

    test "a ground station not trusted does not take a free helm by flying" do
      s = spoken()
      {s, []} = handle(s, {:vehicle, 1, view(%{})})
      assert {_, []} = receive_msg(s, manual(500))
    end
  end

  describe "asking for the helm (MAV_CMD_REQUEST_OPERATOR_CONTROL)" do
    test "a free helm: granted, ACCEPTED" do
      {s, actions} = receive_msg(spoken(), command(32_100, [0, 1, 0, 10]))
      assert [:request_control] = intents(actions)

      {s, actions} =
        handle(s, {:result, ref_of(actions), {:ok, %{status: "granted", grant: %{epoch: 5}}}})

      assert acks(actions) == [{32_100, @accepted}]
      assert Session.piloting(s) == [1]
    end

    test "a piloted helm: the pilot is asked (IN_PROGRESS), then the helm comes (ACCEPTED)" do
      {s, actions} = receive_msg(spoken(), command(32_100, [0, 1, 0, 10]))

      {s, actions} =
        handle(s, {:result, ref_of(actions), {:ok, %{status: "pending", timeout_ms: 10_000}}})

      assert acks(actions) == [{32_100, @in_progress}]
      assert [text] = texts(actions)
      assert text =~ "the pilot is asked (10 s)"

      {s, actions} = handle(s, {:helm, 1, "control_granted", %{epoch: 9}})
      assert acks(actions) == [{32_100, @accepted}]
      assert "rov: you have the helm" in texts(actions)
      assert s.vehicles[1].epoch == 9
      # the request is finished: a second grant acknowledges nothing
      {_s, actions} = handle(s, {:helm, 1, "control_granted", %{epoch: 9}})
      assert acks(actions) == []
    end

    test "a view taken before the grant arrives after it: the helm is still this session's" do
      {s, actions} = receive_msg(spoken(), command(32_100, [0, 1, 0, 10]))

      {s, _} =
        handle(s, {:result, ref_of(actions), {:ok, %{status: "pending", timeout_ms: 10_000}}})

      {s, _} = handle(s, {:helm, 1, "control_granted", %{epoch: 9}})

      # the source's tick, read before the grant (epoch 8, someone else piloting)
      {s, []} = handle(s, {:vehicle, 1, view(%{pilot: %{id: "someone else"}, epoch: 8})})
      assert Session.piloting(s) == [1]
      {s, actions} = receive_msg(s, command(400, [1]))
      assert acks(actions) == [{400, @accepted}]

      # a view as new as the grant is news: the helm went elsewhere
      {s, []} = handle(s, {:vehicle, 1, view(%{pilot: %{id: "someone else"}, epoch: 10})})
      assert Session.piloting(s) == []
    end

    test "refused or timed out: DENIED with the reason" do
      {s, actions} = receive_msg(spoken(), command(32_100, [0, 1, 0, 10]))

      {s, _} =
        handle(s, {:result, ref_of(actions), {:ok, %{status: "pending", timeout_ms: 10_000}}})

      {_s, actions} = handle(s, {:helm, 1, "request_denied", %{reason: "request_timeout"}})
      assert acks(actions) == [{32_100, @denied}]
      assert ["rov: control request denied: request_timeout"] = texts(actions)
    end

    test "the helm's refusals: busy may pass, forbidden does not" do
      {s, actions} = receive_msg(spoken(@observer), command(32_100, [0, 1]))
      {_s, actions} = handle(s, {:result, ref_of(actions), {:error, "forbidden"}})
      assert acks(actions) == [{32_100, @denied}]

      {s, actions} = receive_msg(spoken(), command(32_100, [0, 1]))
      {_s, actions} = handle(s, {:result, ref_of(actions), {:error, "busy"}})
      assert acks(actions) == [{32_100, @temporarily_rejected}]
    end

    test "the main station's request is its takeover" do
      {_s, actions} = receive_msg(spoken(@main), command(32_100, [0, 1]))
      assert [:take_control] = intents(actions)
    end

    test "release (action 0) gives the helm up" do
      {s, actions} = receive_msg(piloting(), command(32_100, [0, 0]))
      assert [:release_control] = intents(actions)
      {_s, actions} = handle(s, {:result, ref_of(actions), {:ok, %{}}})
      assert acks(actions) == [{32_100, @accepted}]
    end

    test "a pilot ground station is asked with the command, and answers with it" do
      s = piloting()

      requester = %{
        id: Party.id(250, "udpin0/127.0.0.1:6000"),
        name: "mp (GCS 250)",
        role: "pilot"
      }

      {s, actions} = handle(s, {:helm, 1, "control_request", %{from: requester}})

      assert [{:send, 1, :command_long, notify}] =
               Enum.filter(actions, &match?({:send, _, :command_long, _}, &1))

      assert %{command: 32_100, param1: 250.0, param2: 1.0, param4: 10.0} = notify
      assert Enum.any?(texts(actions), &(&1 =~ "mp (GCS 250) asks for the helm"))

      {_s, actions} = receive_msg(s, command(32_100, [0, 1, 1]))
      assert [{:answer, true}] = intents(actions)
      {_s, actions} = receive_msg(s, command(32_100, [0, 1, 0]))
      assert [{:answer, false}] = intents(actions)
    end

    test "already the pilot, nobody asking: ACCEPTED" do
      {_s, actions} = receive_msg(piloting(), command(32_100, [0, 1]))
      assert acks(actions) == [{32_100, @accepted}]
    end

    test "losing the helm is said" do
      {s, actions} = handle(piloting(), {:helm, 1, "control_lost", %{reason: "deadman"}})
      assert texts(actions) == ["rov: helm lost (deadman)"]
      assert Session.piloting(s) == []
    end
  end

  describe "commands" do
    test "arming a board without arming: the pilot is armed; others are denied; disarm releases" do
      assert {_, actions} = receive_msg(piloting(), command(400, [1]))
      assert acks(actions) == [{400, @accepted}]

      assert {_, actions} = receive_msg(spoken(), command(400, [1]))
      assert acks(actions) == [{400, @denied}]
      assert [text] = texts(actions)
      assert text =~ "not in control"

      assert {_, actions} = receive_msg(piloting(), command(400, [0]))
      assert [:release_control] = intents(actions)

      assert {_, actions} = receive_msg(piloting(), command(400, [:nan]))
      assert acks(actions) == [{400, @denied}]
    end

    test "arming an ArduSub: asked of the vehicle, acknowledged with its answer" do
      {s, actions} = receive_msg(piloting(@pilot, :mavlink), command(400, [1]))
      assert [{:arm, true}] = intents(actions)

      {_s, actions} =
        handle(s, {:result, ref_of(actions), {:error, "PreArm: Must assign a disarm button"}})

      assert acks(actions) == [{400, @denied}]
      assert texts(actions) == ["rov: PreArm: Must assign a disarm button"]
    end

    test "a trusted ground station arms on a free helm by taking it" do
      {s, _} = receive_msg(session(@trusted), heartbeat())
      {s, []} = handle(s, {:vehicle, 1, view(%{})})
      {s, actions} = receive_msg(s, command(400, [1]))
      assert [:request_control] = intents(actions)

      {_s, actions} =
        handle(s, {:result, ref_of(actions), {:ok, %{status: "granted", grant: %{epoch: 2}}}})

      assert acks(actions) == [{400, @accepted}]
    end

    test "setting a mode: the control commands, pilot only; what cannot map is refused" do
      {_s, actions} = receive_msg(piloting(), command(176, [1, 2]))

      assert [{:commands, [{"autopilot", %{"depth" => "hold", "heading" => "hold"}}]}] =
               intents(actions)

      {_s, actions} =
        receive_msg(
          piloting(),
          msg(:set_mode, %{target_system: 1, base_mode: 1, custom_mode: 16})
        )

      assert [{:commands, [{"set_control_mode", %{"mode" => "dp"}}]}] = intents(actions)

      {_s, actions} = receive_msg(piloting(), command(176, [1, 101]))
      assert acks(actions) == [{176, @denied}]

      {_s, actions} = receive_msg(piloting(), command(176, [0, 2]))
      assert acks(actions) == [{176, @unsupported}]

      {_s, actions} = receive_msg(spoken(), command(176, [1, 2]))
      assert acks(actions) == [{176, @denied}]
    end

    test "lights and camera tilt: servo 9 and 8, the mount and the gimbal manager's pitch" do
      {_s, actions} = receive_msg(piloting(), command(183, [9, 1900]))
      assert [{:commands, [{"set_lights", %{"value" => 255}}]}] = intents(actions)
      {_s, actions} = receive_msg(piloting(), command(183, [9, 1100]))
      assert [{:commands, [{"set_lights", %{"value" => 0}}]}] = intents(actions)
      {_s, actions} = receive_msg(piloting(), command(183, [8, 1900]))
      assert [{:commands, [{"set_tilt", %{"value" => tilt}}]}] = intents(actions)
      assert_in_delta tilt, :math.pi() / 4, 1.0e-9
      {_s, actions} = receive_msg(piloting(), command(205, [-30]))
      assert [{:commands, [{"set_tilt", %{"value" => tilt}}]}] = intents(actions)
      assert_in_delta tilt, -:math.pi() / 6, 1.0e-6
      {_s, actions} = receive_msg(piloting(), command(1000, [10]))
      assert [{:commands, [{"set_tilt", _}]}] = intents(actions)
      {_s, actions} = receive_msg(piloting(), command(183, [3, 1500]))
      assert acks(actions) == [{183, @unsupported}]
      {_s, actions} = receive_msg(spoken(), command(183, [9, 1500]))
      assert acks(actions) == [{183, @denied}]
    end

    test "a command's result is its ACK" do
      {s, actions} = receive_msg(piloting(), command(183, [9, 1500]))
      {_s, actions} = handle(s, {:result, ref_of(actions), {:ok, %{control: %{}}}})
      assert acks(actions) == [{183, @accepted}]
    end

    test "message intervals: set, read back, refused for what is not streamed" do
      {s, actions} = receive_msg(spoken(), command(511, [30, 200_000]))
      assert acks(actions) == [{511, @accepted}]
      {_s, actions} = receive_msg(s, command(510, [30]))
      assert acks(actions) == [{510, @accepted}]

      assert [%{message_id: 30, interval_us: 200_000}] =
               for({:send, 1, :message_interval, f} <- actions, do: f)

      {_s, actions} = receive_msg(s, command(511, [147, 100_000]))
      assert acks(actions) == [{511, @denied}]
    end

    test "a requested message: the ACK, then the message" do
      {_s, actions} = receive_msg(spoken(), command(512, [148]))

      assert [{:send, 1, :command_ack, %{result: @accepted}}, {:frames, 1, [:autopilot_version]}] =
               actions

      {_s, actions} = receive_msg(spoken(), command(512, [30]))
      assert {:frames, 1, [:attitude]} = List.last(actions)
      {_s, actions} = receive_msg(spoken(), command(520, [1]))
      assert {:frames, 1, [:autopilot_version]} = List.last(actions)
      {_s, actions} = receive_msg(spoken(), command(512, [9999]))
      assert acks(actions) == [{512, @unsupported}]
    end

    test "a requested message the vehicle cannot say now (no position) FAILS with the reason; once it can, it comes" do
      {s, []} = handle(spoken(), {:vehicle, 1, Map.put(view(%{}), :messages, [:heartbeat])})
      {_s, actions} = receive_msg(s, command(512, [32]))
      assert acks(actions) == [{512, @failed}]
      assert ["rov: LOCAL_POSITION_NED: the vehicle has no valid position"] = texts(actions)
      refute Enum.any?(actions, &match?({:frames, _, _}, &1))

      {s, []} =
        handle(s, {:vehicle, 1, Map.put(view(%{}), :messages, [:heartbeat, :local_position_ned])})

      {_s, actions} = receive_msg(s, command(512, [32]))
      assert acks(actions) == [{512, @accepted}]
      assert {:frames, 1, [:local_position_ned]} = List.last(actions)
    end

    test "an unknown command is UNSUPPORTED; a command for another system is not ours" do
      {_s, actions} = receive_msg(spoken(), command(42_424, []))
      assert acks(actions) == [{42_424, @unsupported}]
      {s, actions} = receive_msg(spoken(), command(400, [1], 9))
      assert actions == []
      assert s.counters.not_ours == 1
      # target 0 on a node with one vehicle is that vehicle
      {_s, actions} = receive_msg(spoken(), command(42_424, [], 0))
      assert acks(actions) == [{42_424, @unsupported}]
    end

    test "no more than 8 slow intents wait: then TEMPORARILY_REJECTED" do
      s =
        Enum.reduce(1..8, piloting(), fn _, s ->
          {s, actions} = receive_msg(s, command(183, [9, 1500]))
          assert [_] = intents(actions)
          s
        end)

      {_s, actions} = receive_msg(s, command(183, [9, 1500]))
      assert acks(actions) == [{183, @temporarily_rejected}]
    end
  end

  describe "parameters" do
    @sources %{
      control: %{gain: 0.5, lights: 10, tilt: 0.0},
      gains: %{
        "depth" => %{"kp" => 3.0, "ki" => 0.1, "kd" => 1.5},
        "heading" => %{"kp" => 2.0, "ki" => 0.0, "kd" => 0.5}
      },
      limits: %{depth: %{rate: 0.3, accel: 0.2}, heading: %{rate: 0.4, accel: 0.3}},
      helm: %{deadman_ms: 500, request_timeout_ms: 10_000, takeover_ms: 3_000},
      wiring: nil
    }

    defp param_values(actions), do: for({:send, 1, :param_value, f} <- actions, do: f)

    test "the list: every parameter with its index and the count" do
      {s, actions} =
        receive_msg(
          spoken(@observer),
          msg(:param_request_list, %{target_system: 1, target_component: 1})
        )

      assert [:params] = intents(actions)
      {_s, actions} = handle(s, {:result, ref_of(actions), {:ok, @sources}})
      values = param_values(actions)
      assert length(values) == 16
      assert Enum.map(values, & &1.param_index) == Enum.to_list(0..15)
      assert Enum.all?(values, &(&1.param_count == 16 and &1.param_type == 9))
      assert %{param_value: 10.0} = Enum.find(values, &(&1.param_id == "LIGHTS"))
    end

    test "one by name or by index" do
      read = fn id, index ->
        {s, actions} =
          receive_msg(
            spoken(),
            msg(:param_request_read, %{
              target_system: 1,
              target_component: 1,
              param_id: id,
              param_index: index
            })
          )

        {_s, actions} = handle(s, {:result, ref_of(actions), {:ok, @sources}})
        param_values(actions)
      end

      assert [%{param_id: "DEPTH_KP", param_value: 3.0, param_index: 3}] = read.("DEPTH_KP", -1)
      assert [%{param_id: "PILOT_GAIN", param_index: 0}] = read.("", 0)
      assert [] = read.("", 99)
    end

    defp set(s, name, value) do
      receive_msg(
        s,
        msg(:param_set, %{
          target_system: 1,
          target_component: 1,
          param_id: name,
          param_value: value,
          param_type: 9
        })
      )
    end

    test "the pilot sets a control parameter; the value in force comes back" do
      {s, actions} = set(piloting(), "LIGHTS", 128.0)

      assert [{:param_set, "LIGHTS", {:control, "set_lights", %{"value" => 128}}}] =
               intents(actions)

      sources = put_in(@sources.control.lights, 128)
      {_s, actions} = handle(s, {:result, ref_of(actions), {:ok, sources}})
      assert [%{param_id: "LIGHTS", param_value: 128.0}] = param_values(actions)
    end

    test "a refused value answers with the old one and the reason" do
      {s, actions} = set(piloting(), "PILOT_GAIN", 2.0)

      {_s, actions} =
        handle(
          s,
          {:result, ref_of(actions),
           {:error, "value must be a number in [0, 1], got 2.0", @sources}}
        )

      assert [%{param_id: "PILOT_GAIN", param_value: 0.5}] = param_values(actions)

      assert ["rov: PILOT_GAIN refused: value must be a number in [0, 1], got 2.0"] =
               texts(actions)
    end

    test "not the pilot: the old value and why; read-only ones too; unknown ones only why" do
      {s, actions} = set(spoken(), "LIGHTS", 1.0)
      assert [:params] = intents(actions)
      {_s, actions} = handle(s, {:result, ref_of(actions), {:ok, @sources}})
      assert [%{param_value: 10.0}] = param_values(actions)
      assert [text] = texts(actions)
      assert text =~ "not in control"

      {s, actions} = set(piloting(), "DEADMAN_MS", 100.0)
      {_s, actions} = handle(s, {:result, ref_of(actions), {:ok, @sources}})
      assert [%{param_value: 500.0}] = param_values(actions)
      assert [_] = texts(actions)

      {_s, actions} = set(piloting(), "NOPE", 1.0)
      assert param_values(actions) == [] and intents(actions) == []
      assert ["rov: no parameter NOPE"] = texts(actions)
    end

    test "tuning: the pilot or the main station, not an observer" do
      {_s, actions} = set(spoken(@main), "DEPTH_KP", 4.0)
      assert [{:param_set, "DEPTH_KP", {:tune, %{"depth" => %{"kp" => 4.0}}}}] = intents(actions)
      {_s, actions} = set(piloting(), "HDG_KD", 1.0)
      assert [{:param_set, "HDG_KD", {:tune, _}}] = intents(actions)
      {_s, actions} = set(spoken(@observer), "DEPTH_KP", 4.0)
      assert [:params] = intents(actions)
    end
  end

  describe "the rest" do
    test "the mission list is empty, of the type asked" do
      {_s, actions} =
        receive_msg(
          spoken(),
          msg(:mission_request_list, %{target_system: 1, target_component: 1, mission_type: 2})
        )

      assert [{:send, 1, :mission_count, %{count: 0, mission_type: 2}}] = actions
    end

    test "the mission count goes to the station that asked, and encodes" do
      # msg/3 sends as system 255, component 190 (a ground station's ids)
      {_s, [{:send, 1, :mission_count, fields}]} =
        receive_msg(
          spoken(),
          msg(:mission_request_list, %{target_system: 1, target_component: 1, mission_type: 0})
        )

      assert %{target_system: 255, target_component: 190} = fields

      assert {:ok, _} = MAVLink.encode(:mission_count, fields, %{system: 1, component: 1, seq: 0})
    end

    test "TIMESYNC requests are answered with the vehicle's clock" do
      {_s, actions} = receive_msg(spoken(), msg(:timesync, %{tc1: 0, ts1: 123}), 2_000)
      assert [{:send, 1, :timesync, %{tc1: 2_000_000_000, ts1: 123}}] = actions
      # an answer to someone else's request is not ours to answer
      {_s, actions} = receive_msg(spoken(), msg(:timesync, %{tc1: 5, ts1: 123}))
      assert actions == []
    end

    test "REQUEST_DATA_STREAM changes this ground station's rates" do
      {s, []} =
        receive_msg(
          spoken(),
          msg(:request_data_stream, %{
            target_system: 1,
            target_component: 1,
            req_stream_id: 10,
            req_message_rate: 2,
            start_stop: 1
          })
        )

      {_s, actions} = receive_msg(s, command(510, [30]))
      assert [%{interval_us: 500_000}] = for({:send, 1, :message_interval, f} <- actions, do: f)
    end

    test "the streamed messages due: each at its interval" do
      s = spoken()
      {s, due} = Session.due(s, 1, [:heartbeat, :attitude], 0)
      assert Enum.sort(due) == [:attitude, :heartbeat]
      {s, due} = Session.due(s, 1, [:heartbeat, :attitude], 100)
      assert due == [:attitude]
      {_s, due} = Session.due(s, 1, [:heartbeat, :attitude], 1_000)
      assert Enum.sort(due) == [:attitude, :heartbeat]
    end
  end

  describe "properties" do
    test "any message, from any system, in any state: no exception, and every reply encodes" do
      check(
        {Gen.message(), :proper_types.oneof([@pilot, @observer, @main, @trusted]),
         :proper_types.boolean(), :proper_types.integer(0, 255)},
        fn {{name, fields}, identity, pilot?, system} ->
          s = if pilot?, do: piloting(identity), else: spoken(identity)
          {:ok, frame} = MAVLink.encode(name, fields, %{system: system, component: 1, seq: 0})
          {_, [%Message{} = message], _} = MAVLink.decode(MAVLink.new(), frame)
          {_s, actions} = receive_msg(s, message, 10)

          Enum.all?(actions, fn
            {:send, 1, name, fields} ->
              match?({:ok, _}, MAVLink.encode(name, fields, %{system: 1, component: 1, seq: 0}))

            {:frames, 1, names} ->
              is_list(names)

            {:intent, ref, 1, _intent} ->
              is_integer(ref)
          end)
        end,
        500
      )
    end

    test "whatever happens, a session that does not pilot never moves a vehicle" do
      check(
        :proper_types.list(Gen.message(:manual_control)),
        fn messages ->
          s = spoken(@observer)

          {_s, actions} =
            Enum.reduce(messages, {s, []}, fn {:manual_control, fields}, {s, acc} ->
              {s, actions} = receive_msg(s, msg(:manual_control, fields))
              {s, acc ++ actions}
            end)

          not Enum.any?(actions, &match?({:intent, _, _, {:thrust, _, _}}, &1))
        end
      )
    end
  end
end
