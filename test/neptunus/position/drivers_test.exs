defmodule Neptunus.Position.DriversTest do
  @moduledoc """
  The real DVL and Underwater GPS drivers over their protocols: against the simulated
  devices (`Neptunus.Position.Simulated`, fed poses as a simulator publishes them), and
  against test doubles in this file that send what a broken device would.
  """
  use ExUnit.Case, async: true

  @moduletag :capture_log

  alias Neptunus.Camera.Pose
  alias Neptunus.Position.{DVL, Simulated, UGPS}
  alias Neptunus.Protocol.{UnderwaterGPS, WaterLinkedDVL}
  alias Neptunus.PubSub
  alias Neptunus.Vehicle.Navigation

  doctest Neptunus.Position.Source

  defp id, do: "pos-#{System.unique_integer([:positive])}"

  # the test process stands in for the vehicle's navigation: the drivers' reports arrive
  # as casts, and an Underwater GPS driver's question for the depth is answered here
  setup do
    id = id()
    {:ok, _} = Registry.register(Neptunus.Fleet.Registry, {Navigation, id}, nil)
    {:ok, id: id}
  end

  defp next_report(name, pattern_fun, timeout \\ 10_000) do
    receive do
      {:"$gen_cast", {:position, ^name, report, at}} when is_float(at) ->
        if pattern_fun.(report), do: report, else: next_report(name, pattern_fun, timeout)

      {:"$gen_call", from, :water} ->
        GenServer.reply(from, {4.0, 12.5})
        next_report(name, pattern_fun, timeout)
    after
      timeout -> flunk("no matching #{name} report in #{timeout} ms")
    end
  end

  # a simulator publishing the true pose every 50 ms until the test ends
  defp simulate(id, pose) do
    pid =
      spawn_link(fn ->
        Stream.repeatedly(fn ->
          PubSub.broadcast(Pose.topic(id), "pose", pose)
          Process.sleep(50)
        end)
        |> Stream.run()
      end)

    on_exit(fn -> Process.exit(pid, :kill) end)
  end

  @pose %{
    x: 3.0,
    y: -4.0,
    z: 4.0,
    phi: 0.0,
    theta: 0.0,
    psi: 0.0,
    u: 0.2,
    v: -0.1,
    w: 0.0,
    p: 0.0,
    q: 0.0,
    r: 0.0,
    lights: 0.0,
    laser: 0.0,
    tilt: 0.0
  }

  describe "against the simulated devices, over their protocols" do
    test "the DVL driver reads the simulated DVL's velocities and dead reckoning, and commands it",
         %{id: id} do
      start_supervised!(
        {Simulated,
         id: id, name: :dvl, kind: :dvl, settings: [dropout: 0.0, noise: 0.001, noise_per_m: 0.0]}
      )

      simulate(id, @pose)
      assert {:link, :up} = next_report(:dvl, &match?({:link, _}, &1))

      {:velocity, v} = next_report(:dvl, &match?({:velocity, %{valid: true}}, &1))
      assert_in_delta v.vx, 0.2, 0.01
      assert_in_delta v.vy, -0.1, 0.01
      assert_in_delta v.altitude, 26.0, 0.1
      assert v.tracking == :bottom
      assert v.t <= Neptunus.Position.Source.now()

      assert {:dead_reckoning, %{x: x, y: y}} =
               next_report(:dvl, &match?({:dead_reckoning, _}, &1))

      assert is_float(x) and is_float(y)
      assert {:ok, _} = DVL.command(id, :dvl, :reset_dead_reckoning)
      assert {:error, "unknown DVL command :jump"} = DVL.command(id, :dvl, :jump)
    end

    test "the DVL loses bottom lock beyond its range: invalid velocities", %{id: id} do
      start_supervised!(
        {Simulated, id: id, name: :dvl, kind: :dvl, settings: [seabed: 100.0, dropout: 0.0]}
      )

      simulate(id, @pose)
      assert {:velocity, %{valid: false}} = next_report(:dvl, &match?({:velocity, _}, &1))
    end

    test "the Underwater GPS driver sends the depth and reads the simulated topside's fixes",
         %{id: id} do
      start_supervised!(
        {Simulated,
         id: id,
         name: :usbl,
         kind: :usbl,
         settings: [noise: 0.01, noise_per_m: 0.0, outlier: 0.0, dropout: 0.0],
         driver: [poll_ms: 50, depth_ms: 100]}
      )

      simulate(id, @pose)
      assert {:link, :up} = next_report(:usbl, &match?({:link, _}, &1))
      # no fix is valid before the topside has the vehicle's depth: it was sent
      {:fix, fix} = next_report(:usbl, &match?({:fix, %{valid: true}}, &1))
      assert_in_delta fix.north, 3.0, 0.1
      assert_in_delta fix.east, -4.0, 0.1
      assert fix.frame == :usbl
      assert fix.t < Neptunus.Position.Source.now()
    end
  end

  describe "bad input, against test doubles" do
    # a DVL stand-in: the test writes its lines
    defp fake_dvl do
      {:ok, listen} =
        :gen_tcp.listen(0, [:binary, active: false, reuseaddr: true, ip: {127, 0, 0, 1}])

      {:ok, port} = :inet.port(listen)
      {listen, port}
    end

    @velocity %{
      vx: 0.1,
      vy: 0.0,
      vz: 0.0,
      fom: 0.002,
      covariance: nil,
      altitude: 3.0,
      valid: true,
      status: 0,
      time_ms: 100.0,
      time_of_validity_us: 1_000_000,
      time_of_transmission_us: 1_040_000,
      tracking: :bottom,
      transducers: []
    }

    test "the DVL driver: garbage counted, invalid velocity passed as invalid, a close is a disconnect, then it reconnects",
         %{id: id} do
      {listen, port} = fake_dvl()
      start_supervised!({DVL, id: id, name: :dvl, endpoint: fn -> {{127, 0, 0, 1}, port} end})
      {:ok, socket} = :gen_tcp.accept(listen, 5_000)
      assert {:link, :up} = next_report(:dvl, &match?({:link, _}, &1))

      :ok = :gen_tcp.send(socket, "{not json\n")
      assert {:garbage, reason} = next_report(:dvl, &match?({:garbage, _}, &1))
      assert is_binary(reason)

      :ok = :gen_tcp.send(socket, ~s({"type": "velocity", "vx": "fast"}\n))
      assert {:garbage, _} = next_report(:dvl, &match?({:garbage, _}, &1))

      :ok = :gen_tcp.send(socket, String.duplicate("x", 9000) <> "\n")
      assert {:garbage, "a line longer than" <> _} = next_report(:dvl, &match?({:garbage, _}, &1))

      line = WaterLinkedDVL.encode_velocity(%{@velocity | valid: false})
      :ok = :gen_tcp.send(socket, line)
      assert {:velocity, %{valid: false}} = next_report(:dvl, &match?({:velocity, _}, &1))

      line = WaterLinkedDVL.encode_velocity(@velocity)
      :ok = :gen_tcp.send(socket, line)

      assert {:velocity, %{valid: true, vx: vx, t: t}} =
               next_report(:dvl, &match?({:velocity, _}, &1))

      assert_in_delta vx, 0.1, 1.0e-9
      # measured 40 ms before it was sent
      assert t < Neptunus.Position.Source.now() - 0.039

      :ok = :gen_tcp.close(socket)

      assert {:link, {:down, "closed by the DVL"}} = next_report(:dvl, &match?({:link, _}, &1))

      # and it comes back
      {:ok, _again} = :gen_tcp.accept(listen, 10_000)
      assert {:link, :up} = next_report(:dvl, &match?({:link, _}, &1))
    end

    test "the DVL driver: a command without a connection says so", %{id: id} do
      {listen, port} = fake_dvl()
      :gen_tcp.close(listen)
      start_supervised!({DVL, id: id, name: :dvl, endpoint: fn -> {{127, 0, 0, 1}, port} end})
      assert {:link, {:down, reason}} = next_report(:dvl, &match?({:link, _}, &1))
      assert reason =~ "refused"
      assert {:error, "DVL not connected" <> _} = DVL.command(id, :dvl, :calibrate_gyro)
    end

    # an Underwater GPS stand-in answering each request with the next of `answers`
    defp fake_topside(answers) do
      {:ok, listen} =
        :gen_tcp.listen(0, [:binary, active: false, reuseaddr: true, ip: {127, 0, 0, 1}])

      {:ok, port} = :inet.port(listen)
      parent = self()

      pid =
        spawn_link(fn ->
          Enum.each(Stream.cycle([:loop]), fn _ -> serve(listen, parent, answers) end)
        end)

      on_exit(fn -> Process.exit(pid, :kill) end)
      "http://127.0.0.1:#{port}"
    end

    defp serve(listen, parent, answers) do
      {:ok, socket} = :gen_tcp.accept(listen)
      {:ok, request} = :gen_tcp.recv(socket, 0, 5_000)
      [line | _] = String.split(request, "\r\n")

      {status, body} =
        if String.starts_with?(line, "PUT"),
          do: {200, UnderwaterGPS.encode_operation(:ok)},
          else: Agent.get_and_update(answers, fn [a | rest] -> {a, rest ++ [a]} end)

      send(parent, {:topside_request, line})

      :gen_tcp.send(
        socket,
        "HTTP/1.1 #{status} X\r\ncontent-type: application/json\r\ncontent-length: " <>
          "#{byte_size(body)}\r\nconnection: close\r\n\r\n" <> body
      )

      :gen_tcp.close(socket)
    end

    test "the Underwater GPS driver: garbage, HTTP errors and an invalid fix reported as such",
         %{id: id} do
      good =
        UnderwaterGPS.encode_fix(%{x: 1.0, y: 2.0, z: 4.0, std: 0.3, valid: true, receivers: []})

      invalid =
        UnderwaterGPS.encode_fix(%{x: 1.0, y: 2.0, z: 4.0, std: 0.3, valid: false, receivers: []})

      {:ok, answers} =
        Agent.start_link(fn -> [{200, "<html>"}, {500, "boom"}, {200, invalid}, {200, good}] end)

      url = fake_topside(answers)
      start_supervised!({UGPS, id: id, name: :usbl, url: url, poll_ms: 30, depth_ms: 60})

      assert {:garbage, _} = next_report(:usbl, &match?({:garbage, _}, &1))

      assert {:garbage, "HTTP 500" <> _} =
               next_report(:usbl, &match?({:garbage, "HTTP" <> _}, &1))

      assert {:fix, %{valid: false}} = next_report(:usbl, &match?({:fix, _}, &1))

      assert {:fix, %{valid: true, north: 1.0, east: 2.0}} =
               next_report(:usbl, &match?({:fix, _}, &1))

      # it told the topside the depth navigation gave it
      assert_receive {:topside_request, "PUT /api/v1/external/depth" <> _}, 5_000
    end

    test "the Underwater GPS driver: a topside that does not answer is a disconnect", %{id: id} do
      {:ok, listen} = :gen_tcp.listen(0, [:binary, ip: {127, 0, 0, 1}])
      {:ok, port} = :inet.port(listen)
      :gen_tcp.close(listen)

      start_supervised!({UGPS, id: id, name: :usbl, url: "http://127.0.0.1:#{port}", poll_ms: 50})

      assert {:link, {:down, reason}} = next_report(:usbl, &match?({:link, _}, &1))
      assert reason =~ "refused"
    end
  end
end
