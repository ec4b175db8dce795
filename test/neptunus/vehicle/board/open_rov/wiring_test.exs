defmodule Neptunus.Vehicle.Board.OpenROV.WiringTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Vehicle.Board.OpenROV.Wiring

  import Neptunus.Test.Properties

  alias Neptunus.Vehicle.Board.OpenROV.Wiring

  test "the thesis' Neptunus: go(1700,1700,1700) pushed port backwards, so port is reversed" do
    w = Wiring.default()
    assert Wiring.to_us(w, %{port: 0.4, vertical: 0.4, starboard: 0.4}) == {1300, 1700, 1700}
    assert Wiring.from_us(w, {1700, 1700, 1700}) == %{port: -0.4, vertical: 0.4, starboard: 0.4}

    assert Wiring.go_command(w, %{port: 0.0, vertical: 0.0, starboard: 0.0}) ==
             "go(1500,1500,1500,1);"
  end

  test "order and the flag: ramp sends 0" do
    w = %Wiring{order: [:vertical, :starboard, :port], reversed: [:starboard], direct: false}

    assert Wiring.go_command(w, %{port: 1.0, vertical: -1.0, starboard: 0.5}) ==
             "go(1000,1250,2000,0);"
  end

  test "parse and to_string" do
    for text <- [
          "-port/vertical/starboard/direct",
          "port/vertical/starboard/ramp",
          "-starboard/-port/-vertical/direct"
        ] do
      assert {:ok, w} = Wiring.parse(text)
      assert Wiring.to_string(w) == text
    end

    assert Wiring.parse(" -port / vertical / starboard ") == {:ok, Wiring.default()}

    for {bad, message} <- [
          {"", ~r/three motors/},
          {"port/vertical", ~r/three motors/},
          {"port/vertical/starboard/fast", ~r/direct or ramp, not "fast"/},
          {"port/vertical/starboard/smooth",
           ~r/meant the opposite of what the OpenROV firmware does/},
          {"port/vertical/starboard/nosmooth", ~r/direct sends 1, ramp sends 0/},
          {"port/vertical/bow", ~r/exactly once/},
          {"port/vertical/vertical", ~r/exactly once/},
          {"+port/vertical/starboard", ~r/exactly once/}
        ] do
      assert {:error, reason} = Wiring.parse(bad)
      assert reason =~ message, bad
    end
  end

  test "property: from_us inverts to_us to within the 1/500 quantisation, any wiring" do
    motors = [:port, :vertical, :starboard]
    value = bind(:proper_types.integer(-1000, 1000), &(&1 / 1000))

    wiring =
      bind(
        {:proper_types.elements(permutations(motors)),
         :proper_types.list(:proper_types.elements(motors)), :proper_types.bool()},
        fn {order, reversed, direct} ->
          %Wiring{order: order, reversed: Enum.uniq(reversed), direct: direct}
        end
      )

    check(
      {wiring, value, value, value},
      fn {w, p, v, s} ->
        thrusters = %{port: p, vertical: v, starboard: s}
        back = Wiring.from_us(w, Wiring.to_us(w, thrusters))
        Enum.all?(motors, &(abs(back[&1] - thrusters[&1]) <= 0.001 + 1.0e-12))
      end,
      1_000
    )
  end

  defp permutations([]), do: [[]]
  defp permutations(list), do: for(x <- list, rest <- permutations(list -- [x]), do: [x | rest])

  describe "motor modifiers under the firmware's Motor::goms" do
    # ESC offsets from neutral of port and starboard for a forward surge, the board's
    # modifiers set as `mods` ({forward, reverse} in go() order)
    defp surge_offsets(wiring, surge, {forward, reverse}) do
      us = Wiring.to_us(wiring, %{port: surge, vertical: 0.0, starboard: surge})

      esc =
        Enum.zip([Tuple.to_list(us), Tuple.to_list(forward), Tuple.to_list(reverse)])
        |> Enum.map(fn {u, f, r} ->
          Neptunus.Vehicle.Board.OpenROV.Protocol.goms(u, f, r) - 1500
        end)

      positions = Enum.zip(wiring.order, esc) |> Map.new()
      {positions.port, positions.starboard}
    end

    test "with the modifiers we send, a straight surge gives equal port and starboard offsets" do
      wiring = Wiring.default()

      for surge <- [0.1, 0.25, 0.5, 0.8, 1.0] do
        {port, starboard} = surge_offsets(wiring, surge, Wiring.modifiers(wiring))
        assert abs(abs(port) - abs(starboard)) <= 10, "surge #{surge}: #{port} vs #{starboard}"
      end
    end

    test "with the firmware's defaults (forward 100, reverse 200) the reversed port motor gets more" do
      {port, starboard} = surge_offsets(Wiring.default(), 0.4, {{100, 100, 100}, {200, 200, 200}})

      assert abs(port) - abs(starboard) > 100
    end

    test "configured modifiers are sent in go() order; the syntax round-trips" do
      {:ok, w} = Wiring.parse("starboard:200:100/-vertical/port:100:300/ramp")

      assert Wiring.modifier_commands(w) == [
               "mtrmod1(200,100,100);",
               "mtrmod2(100,100,300);"
             ]

      assert Wiring.parse(Wiring.to_string(w)) == {:ok, w}
      assert {:error, "motor modifiers" <> _} = Wiring.parse("port:0:100/vertical/starboard")
      assert {:error, "a motor is NAME" <> _} = Wiring.parse("port:100/vertical/starboard")
    end
  end
end
