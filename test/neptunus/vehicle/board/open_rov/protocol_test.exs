defmodule Neptunus.Vehicle.Board.OpenROV.ProtocolTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Vehicle.Board.OpenROV.Protocol

  import Neptunus.Test.Properties

  alias Neptunus.Vehicle.Board.OpenROV

  @deg :math.pi() / 180

  describe "commands" do
    test "go with smoothing on and off, every corner" do
      for a <- [1000, 1500, 2000], b <- [1000, 1500, 2000], c <- [1000, 1500, 2000] do
        assert OpenROV.Protocol.go({a, b, c}, true) == "go(#{a},#{b},#{c},1);"
        assert OpenROV.Protocol.go({a, b, c}, false) == "go(#{a},#{b},#{c},0);"
      end
    end

    test "encoders refuse out-of-range values (a bug in the caller, not a pilot error)" do
      for bad <- [{999, 1500, 1500}, {1500, 2001, 1500}, {1500, 1500, 1500.0}, {1500, 1500}] do
        assert_raise FunctionClauseError, fn -> OpenROV.Protocol.go(bad, true) end
      end

      assert_raise FunctionClauseError, fn -> OpenROV.Protocol.go({1500, 1500, 1500}, 1) end
      assert_raise FunctionClauseError, fn -> OpenROV.Protocol.lights(256) end
      assert_raise FunctionClauseError, fn -> OpenROV.Protocol.laser(-1) end
      assert_raise FunctionClauseError, fn -> OpenROV.Protocol.tilt(999) end
      assert_raise FunctionClauseError, fn -> OpenROV.Protocol.ping(-1) end
      assert_raise FunctionClauseError, fn -> OpenROV.Protocol.ping(2_147_483_648) end
    end

    test "lights, laser, tilt, ping, stop" do
      assert OpenROV.Protocol.lights(0) == "ligt(0);"
      assert OpenROV.Protocol.laser(255) == "claser(255);"
      assert OpenROV.Protocol.tilt(2000) == "tilt(2000);"
      assert OpenROV.Protocol.ping(0) == "ping(0);"
      assert OpenROV.Protocol.ping(2_147_483_647) == "ping(2147483647);"
      assert OpenROV.Protocol.stop() == "stop();"
    end

    test "the board's parser reads every command back" do
      for cmd <- [
            OpenROV.Protocol.lights(12),
            OpenROV.Protocol.laser(200),
            OpenROV.Protocol.tilt(1234),
            OpenROV.Protocol.ping(99),
            OpenROV.Protocol.stop()
          ] do
        assert {:ok, _} = OpenROV.Protocol.parse_command(cmd)
      end

      assert OpenROV.Protocol.parse_command("ligt(12);") == {:ok, {:ligt, 12}}
      assert OpenROV.Protocol.parse_command("claser(200)") == {:ok, {:claser, 200}}
      assert OpenROV.Protocol.parse_command(" tilt(1234) ") == {:ok, {:tilt, 1234}}
      assert OpenROV.Protocol.parse_command("ping(99)") == {:ok, {:ping, 99}}
      assert OpenROV.Protocol.parse_command("stop()") == {:ok, :stop}
    end

    test "the board's parser refuses corrupt commands" do
      for bad <- [
            "",
            "go",
            "go(1500,1500,1500)",
            "go(1500,1500,1500,2)",
            "go(1500,1500,15x0,1)",
            "go(1500,1500,1500,1",
            "ligt(256)",
            "claser(-1)",
            "tilt(3000)",
            "ping(-4)",
            "stop(1)",
            "warp(9)",
            "GO(1500,1500,1500,1)",
            <<0xFF, 0xFE>>
          ] do
        assert {:error, reason} = OpenROV.Protocol.parse_command(bad), inspect(bad)
        assert is_binary(reason)
      end
    end

    test "split_commands keeps the incomplete tail" do
      assert OpenROV.Protocol.split_commands("") == {[], ""}
      assert OpenROV.Protocol.split_commands("stop();") == {["stop()"], ""}
      assert OpenROV.Protocol.split_commands(";;ping(1);\n") == {["ping(1)"], "\n"}
    end
  end

  describe "telemetry lines" do
    test "every known key, converted to SI" do
      line =
        "hdgd:90;deap:1.25;pitc:-10;roll:45.5;yaw:-90;fthr:50;vout:12.1;iout:0.75;" <>
          "temp:11.5;pres:1113.8;time:12345"

      assert {fields, []} = OpenROV.Protocol.parse_line(line)
      assert_in_delta fields.heading, 90 * @deg, 1.0e-12
      assert fields.depth == 1.25
      assert_in_delta fields.pitch, -10 * @deg, 1.0e-12
      assert_in_delta fields.roll, 45.5 * @deg, 1.0e-12
      assert_in_delta fields.yaw, -90 * @deg, 1.0e-12
      assert fields.forward_thrust == 0.5
      assert fields.voltage == 12.1
      assert fields.current == 0.75
      assert fields.temperature == 11.5
      assert_in_delta fields.pressure, 111_380.0, 1.0e-6
      assert fields.board_time == 12.345
      assert map_size(fields) == 11
    end

    test "heading 360° wraps to 0, and both ends of every range are accepted" do
      assert {%{heading: +0.0}, []} = OpenROV.Protocol.parse_line("hdgd:360")

      for {key, {field, min, max, _}} <- OpenROV.Protocol.known() do
        for value <- [min, max] do
          assert {%{^field => _}, []} = OpenROV.Protocol.parse_line("#{key}:#{value}"),
                 "#{key}:#{value}"
        end
      end
    end

    test "just outside every range is a wild point" do
      for {key, {_field, min, max, _}} <- OpenROV.Protocol.known(),
          value <- [min - 0.01, max + 0.01] do
        raw = :erlang.float_to_binary(value * 1.0, decimals: 2)

        assert OpenROV.Protocol.parse_line("#{key}:#{raw}") == {%{}, [{:out_of_range, key, raw}]},
               "#{key}:#{raw}"
      end
    end

    test "the thesis' wild points: decades off, angles out of range, a key as a value" do
      {fields, rejects} =
        OpenROV.Protocol.parse_line("vout:121.0;iout:40;pitc:200;roll:-300;hdgd:pitc;deap:2000")

      assert fields == %{}

      assert rejects == [
               {:out_of_range, "vout", "121.0"},
               {:out_of_range, "iout", "40"},
               {:out_of_range, "pitc", "200"},
               {:out_of_range, "roll", "-300"},
               {:key_as_value, "hdgd", "pitc"},
               {:out_of_range, "deap", "2000"}
             ]

      assert Enum.all?(rejects, &OpenROV.Protocol.wild_point?/1)
    end

    test "a key's name as the value of an unknown key is a wild point as well" do
      assert OpenROV.Protocol.parse_line("motors:deap") ==
               {%{}, [{:key_as_value, "motors", "deap"}]}
    end

    test "numbers the Arduino can print, and things that are not numbers" do
      for {raw, value} <- [
            {"12", 12.0},
            {"-0.00", 0.0},
            {"+3.5", 3.5},
            {"5.", 5.0},
            {".5", 0.5},
            {"1e1", 10.0},
            {"1.5E-1", 0.15}
          ] do
        assert {%{depth: ^value}, []} = OpenROV.Protocol.parse_line("deap:" <> raw), raw
      end

      for raw <- [
            "nan",
            "inf",
            "-inf",
            "ovf",
            "1.2.3",
            "0x10",
            "1e",
            "e5",
            "",
            "-",
            ".",
            "1 2",
            "1e999"
          ] do
        assert {%{}, [{:not_a_number, "deap", ^raw}]} =
                 OpenROV.Protocol.parse_line("deap:" <> raw),
               raw
      end
    end

    test "unknown keys are kept raw, including values with colons and commas" do
      line = "cmd:go(1500,1500,1500,1);motors:1500,1500,1500;cmpd:Jan  1 2015, 12:00:00;fmem:1234"

      assert OpenROV.Protocol.parse_line(line) ==
               {%{
                  "cmd" => "go(1500,1500,1500,1)",
                  "motors" => "1500,1500,1500",
                  "cmpd" => "Jan  1 2015, 12:00:00",
                  "fmem" => "1234"
                }, []}
    end

    test "malformed fields are dropped; empty fields and spaces are ignored" do
      assert OpenROV.Protocol.parse_line("") == {%{}, []}
      assert OpenROV.Protocol.parse_line(";;; ;") == {%{}, []}
      assert OpenROV.Protocol.parse_line(" deap : 1.5 ;") == {%{depth: 1.5}, []}

      assert OpenROV.Protocol.parse_line("deap1.5;:3;1x:2;é:1;deap:2") ==
               {%{depth: 2.0},
                [
                  {:malformed, nil, "deap1.5"},
                  {:malformed, nil, ":3"},
                  {:malformed, nil, "1x:2"},
                  {:malformed, nil, "é:1"}
                ]}

      assert [{:malformed, nil, raw}] =
               elem(OpenROV.Protocol.parse_line(String.duplicate("x", 100)), 1)

      assert byte_size(raw) == 32
    end

    test "a repeated key: the last accepted value wins" do
      assert OpenROV.Protocol.parse_line("deap:1;deap:2;deap:9999") ==
               {%{depth: 2.0}, [{:out_of_range, "deap", "9999"}]}
    end

    test "keys are case-sensitive: HDGD is an unknown key" do
      assert OpenROV.Protocol.parse_line("HDGD:400") == {%{"HDGD" => "400"}, []}
    end

    test "format_line is parse_line's inverse for known fields" do
      fields = [
        heading: 1.0,
        depth: 2.5,
        pitch: -0.2,
        roll: 0.3,
        yaw: -1.0,
        forward_thrust: 0.25,
        voltage: 12.0,
        current: 1.5,
        temperature: 10.0,
        pressure: 101_325.0,
        board_time: 12.0
      ]

      {parsed, []} = OpenROV.Protocol.parse_line(OpenROV.Protocol.format_line(fields, 6))

      for {field, value} <- fields do
        assert_in_delta parsed[field], value, 1.0e-5, "#{field}"
      end
    end
  end

  describe "30.x framing (CRC-8 prefix)" do
    test "crc8 is the Dallas/Maxim CRC-8: published check value and known bytes" do
      # CRC-8/MAXIM check value over "123456789"
      assert OpenROV.Protocol.crc8("123456789") == 0xA1
      assert OpenROV.Protocol.crc8("") == 0
      assert OpenROV.Protocol.crc8(<<0>>) == 0
      assert OpenROV.Protocol.crc8(<<1>>) == 0x5E
    end

    test "2.5 sends plain text, 30 prefixes the CRC of the command, ; included" do
      assert OpenROV.Protocol.frame("go(1500,1500,1500,1);", :openrov_25) ==
               "go(1500,1500,1500,1);"

      <<crc, rest::binary>> = OpenROV.Protocol.frame("go(1500,1500,1500,1);", :openrov_30)
      assert rest == "go(1500,1500,1500,1);"
      assert crc == OpenROV.Protocol.crc8("go(1500,1500,1500,1);")
    end

    test "a command whose CRC would be ';' is re-spaced, never sent with that byte" do
      # find real commands whose CRC is ';' (about 1 in 256)
      hits =
        for n <- 0..3000,
            OpenROV.Protocol.crc8(OpenROV.Protocol.ping(n)) == ?;,
            do: OpenROV.Protocol.ping(n)

      assert hits != []

      for command <- hits do
        <<crc, text::binary>> = framed = OpenROV.Protocol.frame(command, :openrov_30)
        assert crc != ?;
        assert text != command
        assert String.replace(text, " ", "") == command
        assert {:ok, ^text} = OpenROV.Protocol.unframe(framed)
        # the board's parser reads the same command
        assert OpenROV.Protocol.parse_command(text) == OpenROV.Protocol.parse_command(command)
      end
    end

    test "unframe reports the computed and received CRC on a mismatch" do
      assert OpenROV.Protocol.unframe(<<0x12, "ping(1);">>) ==
               {:error, {OpenROV.Protocol.crc8("ping(1);"), 0x12}}

      assert OpenROV.Protocol.unframe("") == {:error, :empty}
    end

    test "property: every go() frames to a CRC that is never ';' and checks on the board" do
      us = :proper_types.integer(1000, 2000)

      check(
        {us, us, us, :proper_types.bool()},
        fn {a, b, c, s} ->
          command = OpenROV.Protocol.go({a, b, c}, s)
          <<crc, _::binary>> = framed = OpenROV.Protocol.frame(command, :openrov_30)
          {:ok, text} = OpenROV.Protocol.unframe(framed)

          crc != ?; and
            OpenROV.Protocol.parse_command(text) == OpenROV.Protocol.parse_command(command)
        end,
        3_000
      )
    end
  end

  describe "firmware lines: mtrmod, goms, pong, echo, crc, dotted keys, text lines" do
    test "mtrmod1/2 encode and parse back; out-of-range modifiers are refused by the encoder" do
      assert OpenROV.Protocol.parse_command(OpenROV.Protocol.mtrmod1({100, 200, 300})) ==
               {:ok, {:mtrmod1, 100, 200, 300}}

      assert OpenROV.Protocol.parse_command("mtrmod2(100,-100,100);") ==
               {:ok, {:mtrmod2, 100, -100, 100}}

      assert {:error, _} = OpenROV.Protocol.parse_command("mtrmod1(100,100);")
      assert {:error, _} = OpenROV.Protocol.parse_command("mtrmod1(100,100,40000);")
      assert_raise FunctionClauseError, fn -> OpenROV.Protocol.mtrmod1({100, 100, 1100}) end
    end

    test "goms: the firmware defaults double reverse and step out of the dead zone" do
      assert Enum.map(
               [1000, 1250, 1300, 1499, 1500, 1501, 1700, 2000],
               &OpenROV.Protocol.goms(&1, 100, 200)
             ) ==
               [1000, 1000, 1090, 1448, 1500, 1550, 1730, 2000]

      # modifiers 100/100: symmetric about neutral (within the map()'s integer truncation)
      for d <- 1..500 do
        up = OpenROV.Protocol.goms(1500 + d, 100, 100) - 1500
        down = 1500 - OpenROV.Protocol.goms(1500 - d, 100, 100)
        assert abs(up - down) <= 1
      end

      # only multiples of 100 count (integer division)
      assert OpenROV.Protocol.goms(1300, 100, 150) == OpenROV.Protocol.goms(1300, 100, 100)
    end

    test "a glued pong, dotted keys and a line starting with ';' parse without rejects" do
      assert {%{"pong" => "1,183422", heading: _}, []} =
               OpenROV.Protocol.parse_line("pong:1,183422;hdgd:1.00;")

      assert {%{"BNO055.status" => "1", "Depth.C0" => "4000"}, []} =
               OpenROV.Protocol.parse_line("BNO055.status:1;Depth.C0:4000;")

      assert {%{board_time: 181.0}, []} = OpenROV.Protocol.parse_line(";time:181000;")

      assert {%{"crc" => "pass", "cmd" => "go(1500,1500,1500,0)"}, []} =
               OpenROV.Protocol.parse_line("crc:pass;cmd:go(1500,1500,1500,0);")

      assert {%{"rawcmd" => "A3,70,69,"}, []} = OpenROV.Protocol.parse_line("rawcmd:A3,70,69,;")
    end

    test "property: parse_pong reads every pong the firmware prints" do
      check(
        {:proper_types.integer(0, 10), :proper_types.integer(0, 4_294_967_295)},
        fn {args, ms} ->
          OpenROV.Protocol.parse_pong("#{args},#{ms}") == {:ok, %{args: args, millis: ms}}
        end,
        1_000
      )
    end

    test "property: parse_crc reads every crc line the 30.x firmware prints" do
      byte = :proper_types.integer(0, 255)

      check(
        {byte, byte},
        fn {c, r} ->
          text = "fail," <> Integer.to_string(c, 16) <> "/" <> Integer.to_string(r, 16)
          OpenROV.Protocol.parse_crc(text) == {:ok, {:fail, c, r}}
        end,
        1_000
      )
    end

    test "property: the echo of any command names it" do
      us = :proper_types.integer(1000, 2000)

      check(
        {us, us, us, :proper_types.bool(), :proper_types.integer(0, 255)},
        fn {a, b, c, s, n} ->
          Enum.all?(
            [
              {OpenROV.Protocol.go({a, b, c}, s), "go"},
              {OpenROV.Protocol.lights(n), "ligt"},
              {OpenROV.Protocol.mtrmod1({100, 100, 100}), "mtrmod1"}
            ],
            fn {command, name} ->
              OpenROV.Protocol.parse_echo(String.trim_trailing(command, ";")) == {:ok, name}
            end
          )
        end,
        500
      )
    end

    test "property: the echo of any command we write reads back as the command's call" do
      us = :proper_types.integer(1000, 2000)
      byte = :proper_types.integer(0, 255)

      check(
        {us, us, us, :proper_types.bool(), byte, byte, byte},
        fn {a, b, c, s, n, m, k} ->
          Enum.all?(
            [
              OpenROV.Protocol.go({a, b, c}, s),
              OpenROV.Protocol.lights(n),
              OpenROV.Protocol.laser(m),
              OpenROV.Protocol.tilt(a),
              OpenROV.Protocol.mtrmod1({n * 3, m, k}),
              OpenROV.Protocol.mtrmod2({k, n, m})
            ],
            fn command ->
              # what the firmware prints: the pieces it split the command into, joined by
              # commas (the 30.x frame may add a space after '(': it is split away)
              {name, args} = OpenROV.Protocol.call(command)
              echo = name <> "(" <> Enum.join(args, ",") <> ")"
              framed = OpenROV.Protocol.frame(command, :openrov_30)
              <<_crc, text::binary>> = framed

              OpenROV.Protocol.parse_call(echo) == {:ok, name, args} and
                OpenROV.Protocol.call(text) == {name, args}
            end
          )
        end,
        500
      )
    end

    test "property: pong, echo and crc parsers never crash on random values" do
      check(
        :proper_types.binary(),
        fn bytes ->
          (OpenROV.Protocol.parse_pong(bytes) == :error or
             match?({:ok, %{}}, OpenROV.Protocol.parse_pong(bytes))) and
            (match?({:ok, _}, OpenROV.Protocol.parse_echo(bytes)) or
               OpenROV.Protocol.parse_echo(bytes) == :error) and
            (match?({:ok, _, _}, OpenROV.Protocol.parse_call(bytes)) or
               OpenROV.Protocol.parse_call(bytes) == :error) and
            (match?({:ok, _}, OpenROV.Protocol.parse_crc(bytes)) or
               OpenROV.Protocol.parse_crc(bytes) == :error) and
            is_boolean(OpenROV.Protocol.text_line?(bytes))
        end,
        2_000
      )
    end

    test "text lines: the 2.5.2 depth driver's, and nothing with fields" do
      assert OpenROV.Protocol.text_line?("Second-Order Temperature in Degrees C is -1.25")
      assert OpenROV.Protocol.text_line?("Depth Sensor: initialized I2C")
      refute OpenROV.Protocol.text_line?("Depth Sensor: initialized I2C;deap:1.0")
      refute OpenROV.Protocol.text_line?("hello world")
    end
  end

  describe "properties" do
    test "parse_line never crashes on random bytes and returns the documented shape" do
      check(:proper_types.binary(), &shape?(OpenROV.Protocol.parse_line(&1)), 2_000)
    end

    test "parse_line never crashes on random UTF-8" do
      check(:proper_unicode.utf8(), &shape?(OpenROV.Protocol.parse_line(&1)), 1_000)
    end

    test "no out-of-range value ever gets through, whatever the line" do
      check(line_gen(), &all_in_range?(OpenROV.Protocol.parse_line(&1)), 3_000)
    end

    test "mutated valid lines: never a crash, never an out-of-range value" do
      check(mutated_line_gen(), &all_in_range?(OpenROV.Protocol.parse_line(&1)), 3_000)
    end

    test "a known field is accepted exactly when its value is a number within range" do
      gen =
        bind({:proper_types.elements(Map.keys(OpenROV.Protocol.known())), number_gen()}, fn {k, n} ->
          {k, n}
        end)

      check(
        gen,
        fn {key, raw} ->
          {field, min, max, _} = OpenROV.Protocol.known()[key]
          {fields, rejects} = OpenROV.Protocol.parse_line("#{key}:#{raw}")
          {value, ""} = Float.parse(raw)

          if value >= min and value <= max,
            do: Map.has_key?(fields, field) and rejects == [],
            else: fields == %{} and rejects == [{:out_of_range, key, raw}]
        end,
        2_000
      )
    end

    test "go encodes and the board's parser decodes the same values" do
      us = :proper_types.integer(1000, 2000)

      check(
        {us, us, us, :proper_types.bool()},
        fn {a, b, c, s} ->
          OpenROV.Protocol.parse_command(OpenROV.Protocol.go({a, b, c}, s)) ==
            {:ok, {:go, a, b, c, if(s, do: 1, else: 0)}}
        end,
        1_000
      )
    end

    test "ping, lights, laser, tilt round-trip" do
      check(
        {:proper_types.integer(0, 2_147_483_647), :proper_types.integer(0, 255),
         :proper_types.integer(1000, 2000)},
        fn {n, byte, us} ->
          OpenROV.Protocol.parse_command(OpenROV.Protocol.ping(n)) == {:ok, {:ping, n}} and
            OpenROV.Protocol.parse_command(OpenROV.Protocol.lights(byte)) == {:ok, {:ligt, byte}} and
            OpenROV.Protocol.parse_command(OpenROV.Protocol.laser(byte)) == {:ok, {:claser, byte}} and
            OpenROV.Protocol.parse_command(OpenROV.Protocol.tilt(us)) == {:ok, {:tilt, us}}
        end,
        500
      )
    end

    test "the board's command parser never crashes on random bytes" do
      check(
        :proper_types.binary(),
        fn bytes ->
          {commands, _rest} = OpenROV.Protocol.split_commands(bytes)
          Enum.all?([bytes | commands], &match?({_, _}, OpenROV.Protocol.parse_command(&1)))
        end,
        1_000
      )
    end
  end

  # Generators ------------------------------------------------------------------------------

  @keys Map.keys(OpenROV.Protocol.known())

  # numbers as the board prints them, inside and outside every range
  defp number_gen do
    bind({:proper_types.integer(-100_000, 100_000), :proper_types.integer(0, 3)}, fn {n, d} ->
      :erlang.float_to_binary(n / 10, decimals: d)
    end)
  end

  defp field_gen do
    key = :proper_types.elements(@keys)

    :proper_types.oneof([
      bind({key, number_gen()}, fn {k, n} -> "#{k}:#{n}" end),
      bind({key, :proper_types.elements(@keys)}, fn {k, v} -> "#{k}:#{v}" end),
      bind({key, :proper_types.binary()}, fn {k, v} -> "#{k}:#{v}" end),
      bind({:proper_types.binary(), :proper_types.binary()}, fn {k, v} -> "#{k}:#{v}" end),
      :proper_types.binary()
    ])
  end

  defp line_gen, do: bind(:proper_types.list(field_gen()), &Enum.join(&1, ";"))

  defp valid_line_gen do
    bind(:proper_types.list({:proper_types.elements(@keys), number_gen()}), fn fields ->
      Enum.map_join(fields, "", fn {k, n} -> "#{k}:#{n};" end)
    end)
  end

  # delete, insert, replace bytes; truncate; multiply by a decade (the thesis' buffer errors)
  defp mutation_gen do
    pos = :proper_types.non_neg_integer()

    :proper_types.oneof([
      {:delete, pos},
      {:insert, pos, :proper_types.byte()},
      {:replace, pos, :proper_types.byte()},
      {:insert, pos, :proper_types.elements([?;, ?:, ?., ?-, ?\r, ?0])},
      {:truncate, pos},
      {:decade, pos}
    ])
  end

  defp mutated_line_gen do
    bind({valid_line_gen(), :proper_types.list(mutation_gen())}, fn {line, mutations} ->
      Enum.reduce(mutations, line, &mutate/2)
    end)
  end

  defp mutate(_mutation, ""), do: ""

  defp mutate({:delete, p}, line) do
    p = rem(p, byte_size(line))
    binary_part(line, 0, p) <> binary_part(line, p + 1, byte_size(line) - p - 1)
  end

  defp mutate({:insert, p, byte}, line) do
    p = rem(p, byte_size(line) + 1)
    binary_part(line, 0, p) <> <<byte>> <> binary_part(line, p, byte_size(line) - p)
  end

  defp mutate({:replace, p, byte}, line) do
    p = rem(p, byte_size(line))
    binary_part(line, 0, p) <> <<byte>> <> binary_part(line, p + 1, byte_size(line) - p - 1)
  end

  defp mutate({:truncate, p}, line), do: binary_part(line, 0, rem(p, byte_size(line)))

  defp mutate({:decade, p}, line) do
    # insert a "0" before the point (x10) or after it (x0.1)
    case :binary.matches(line, ".") do
      [] -> line
      dots -> mutate({:insert, elem(Enum.at(dots, rem(p, length(dots))), 0), ?0}, line)
    end
  end

  defp shape?({fields, rejects}) when is_map(fields) and is_list(rejects) do
    Enum.all?(fields, fn
      {k, v} when is_atom(k) -> is_float(v)
      {k, v} when is_binary(k) -> is_binary(v)
    end) and
      Enum.all?(rejects, fn {reason, key, raw} ->
        reason in [:malformed, :not_a_number, :out_of_range, :key_as_value] and
          (is_nil(key) or is_binary(key)) and is_binary(raw) and byte_size(raw) <= 32
      end)
  end

  defp all_in_range?({fields, _rejects} = result) do
    shape?(result) and
      Enum.all?(fields, fn
        {field, value} when is_atom(field) ->
          {min, max} = OpenROV.Protocol.si_range(field)
          value >= min and value <= max and (field != :heading or value < max)

        {_key, value} ->
          value not in @keys
      end)
  end
end
