defmodule NeptunusWeb.Channels.WireTest do
  use ExUnit.Case, async: true

  alias NeptunusWeb.Channels.Wire
  alias NeptunusWeb.Channels.Wire.Message

  doctest Wire

  @no_partial %{join_ref: nil, ref: nil, topic: nil}

  describe "decode/1 accepts valid frames" do
    test "all fields set" do
      assert Wire.decode(~s(["1","2","vehicle:a","thrust",{"surge":0.5,"yaw":-1}])) ==
               {:ok,
                %Message{
                  join_ref: "1",
                  ref: "2",
                  topic: "vehicle:a",
                  event: "thrust",
                  payload: %{"surge" => 0.5, "yaw" => -1}
                }}
    end

    test "heartbeat with null join_ref" do
      assert {:ok, %Message{join_ref: nil, ref: "7", topic: "phoenix", event: "heartbeat"} = m} =
               Wire.decode(~s([null,"7","phoenix","heartbeat",{}]))

      assert m.payload == %{}
    end

    test "broadcast-shaped frame with both refs null" do
      assert {:ok, %Message{join_ref: nil, ref: nil, topic: "fleet", event: "status"}} =
               Wire.decode(~s([null,null,"fleet","status",{"n":1}]))
    end

    test "whitespace around and inside the frame" do
      assert {:ok, %Message{topic: "t", event: "e", payload: %{"a" => nil}}} =
               Wire.decode(" \n\t[ \"1\" , \"2\" ,\"t\",\"e\", { \"a\" : null } ]\r\n ")
    end

    test "nested payloads and JSON nulls" do
      frame =
        ~s(["1","2","vehicle:a","autopilot",{"depth":{"on":true,"setpoint":1.25,"gains":[1,2,null]},"heading":null}])

      assert {:ok, %Message{payload: payload}} = Wire.decode(frame)

      assert payload == %{
               "depth" => %{"on" => true, "setpoint" => 1.25, "gains" => [1, 2, nil]},
               "heading" => nil
             }
    end

    test "unicode strings, escapes and surrogate pairs" do
      frame = ~s(["ø","\\u00e6","vehicle:å☃","ev😀",{"name":"Ægir \\ud83d\\ude00","nl":"a\\nb"}])

      assert {:ok, %Message{join_ref: "ø", ref: "æ", topic: "vehicle:å☃", event: "ev😀"} = m} =
               Wire.decode(frame)

      assert m.payload == %{"name" => "Ægir 😀", "nl" => "a\nb"}
    end

    test "big integers and floats keep their value" do
      assert {:ok, %Message{payload: %{"big" => big, "f" => f, "neg" => -0.0}}} =
               Wire.decode(
                 ~s(["1","2","t","e",{"big":123456789012345678901234567890,"f":1.0e308,"neg":-0.0}])
               )

      assert big == 123_456_789_012_345_678_901_234_567_890
      assert f == 1.0e308
    end

    test "duplicate payload keys: the last one wins" do
      assert {:ok, %Message{payload: %{"a" => 2}}} =
               Wire.decode(~s(["1","2","t","e",{"a":1,"a":2}]))
    end

    test "decoded strings do not keep the frame binary alive" do
      frame = ~s(["1","2","vehicle:a","thrust",{"pad":"#{String.duplicate("x", 1000)}"}])
      {:ok, %Message{topic: topic}} = Wire.decode(frame)
      assert :binary.referenced_byte_size(topic) == byte_size(topic)
    end
  end

  describe "decode/1 rejects invalid JSON" do
    test "empty input" do
      assert Wire.decode("") == {:error, "empty frame", @no_partial}
    end

    test "whitespace only" do
      assert {:error, "invalid JSON at byte 4: unexpected end of input", @no_partial} =
               Wire.decode("   ")
    end

    test "truncated frame" do
      assert Wire.decode(~s(["1","2","t")) ==
               {:error, "invalid JSON at byte 13: unexpected end of input", @no_partial}
    end

    test "garbage" do
      assert {:error, "invalid JSON at byte 1: invalid JSON", @no_partial} = Wire.decode("hello")
      assert {:error, "invalid JSON at byte 1: invalid JSON", @no_partial} = Wire.decode(<<0>>)
    end

    test "bad literal and bad number" do
      assert {:error, "invalid JSON at byte 2: invalid literal" <> _, @no_partial} =
               Wire.decode("[tru]")

      assert {:error, "invalid JSON at byte 4: invalid number", @no_partial} = Wire.decode("[1e]")
    end

    test "trailing data after the frame" do
      assert {:error, "invalid JSON at byte 22: unexpected data after the JSON value",
              @no_partial} = Wire.decode(~s(["1","2","t","e",{}] []))
    end

    test "invalid UTF-8 in a string" do
      assert {:error, "invalid JSON at byte 3: invalid string" <> _, @no_partial} =
               Wire.decode(<<"[\"", 0xFF, "\",null,\"t\",\"e\",{}]">>)

      # overlong encoding of "/"
      assert {:error, "invalid JSON at byte" <> _, @no_partial} =
               Wire.decode(<<"[null,null,\"t\",\"", 0xC0, 0xAF, "\",{}]">>)
    end

    test "lone surrogate escape" do
      assert {:error, "invalid JSON at byte" <> _, @no_partial} =
               Wire.decode(~s(["\\ud800",null,"t","e",{}]))
    end

    test "numbers out of range" do
      assert Wire.decode(~s(["1","2","t","e",{"x":1e999999}])) ==
               {:error, "invalid JSON: number out of range", @no_partial}

      assert Wire.decode("1.5e400") == {:error, "invalid JSON: number out of range", @no_partial}
    end

    test "huge integer decodes (and is then rejected as a frame)" do
      digits = String.duplicate("9", 20_000)

      assert {:error, "frame must be a JSON array" <> _, @no_partial} = Wire.decode(digits)

      assert {:ok, %Message{payload: %{"n" => n}}} =
               Wire.decode(~s([null,null,"t","e",{"n":#{digits}}]))

      assert n == String.to_integer(digits)
    end

    test "deep nesting" do
      deep = String.duplicate("[", 100_000) <> String.duplicate("]", 100_000)
      assert {:error, "frame must have 5 elements, got 1", @no_partial} = Wire.decode(deep)

      payload = String.duplicate(~s({"a":), 10_000) <> "1" <> String.duplicate("}", 10_000)
      assert {:ok, %Message{}} = Wire.decode(~s(["1","2","t","e",#{payload}]))

      unbalanced = String.duplicate("[", 100_000)

      assert {:error, "invalid JSON at byte 100001: unexpected end of input", @no_partial} =
               Wire.decode(unbalanced)
    end

    test "non-binary input" do
      assert Wire.decode(~c"[]") == {:error, "frame must be a binary", @no_partial}
      assert Wire.decode(nil) == {:error, "frame must be a binary", @no_partial}
    end
  end

  describe "decode/1 rejects badly shaped frames" do
    @not_array "frame must be a JSON array [join_ref, ref, topic, event, payload]"

    test "non-array JSON values" do
      for json <- ["42", "-1.5", ~s("text"), "true", "null", ~s({"topic":"t"}), "{}"] do
        assert Wire.decode(json) == {:error, @not_array, @no_partial}, json
      end
    end

    test "wrong arity" do
      assert Wire.decode("[]") == {:error, "frame must have 5 elements, got 0", @no_partial}

      assert Wire.decode(~s(["1","2","vehicle:a","thrust"])) ==
               {:error, "frame must have 5 elements, got 4",
                %{join_ref: "1", ref: "2", topic: "vehicle:a"}}

      assert Wire.decode(~s(["1","2","vehicle:a","thrust",{},{}])) ==
               {:error, "frame must have 5 elements, got 6",
                %{join_ref: "1", ref: "2", topic: "vehicle:a"}}

      assert Wire.decode(~s(["1"])) ==
               {:error, "frame must have 5 elements, got 1",
                %{join_ref: "1", ref: nil, topic: nil}}
    end

    test "join_ref of the wrong type" do
      for bad <- ["1", "1.5", "true", "[]", "{}"] do
        assert Wire.decode(~s([#{bad},"2","vehicle:a","thrust",{}])) ==
                 {:error, "join_ref must be a string or null",
                  %{join_ref: nil, ref: "2", topic: "vehicle:a"}},
               bad
      end
    end

    test "ref of the wrong type (integers are not converted)" do
      for bad <- ["2", "2.0", "false", ~s(["2"]), ~s({"r":2})] do
        assert Wire.decode(~s(["1",#{bad},"vehicle:a","thrust",{}])) ==
                 {:error, "ref must be a string or null",
                  %{join_ref: "1", ref: nil, topic: "vehicle:a"}},
               bad
      end
    end

    test "topic missing, empty or of the wrong type" do
      for bad <- [~s(""), "null", "3", "[]", "{}"] do
        assert Wire.decode(~s(["1","2",#{bad},"thrust",{}])) ==
                 {:error, "topic must be a non-empty string",
                  %{join_ref: "1", ref: "2", topic: nil}},
               bad
      end
    end

    test "event missing, empty or of the wrong type" do
      for bad <- [~s(""), "null", "3", "true", "[]", "{}"] do
        assert Wire.decode(~s(["1","2","vehicle:a",#{bad},{}])) ==
                 {:error, "event must be a non-empty string",
                  %{join_ref: "1", ref: "2", topic: "vehicle:a"}},
               bad
      end
    end

    test "payload that is not an object keeps the partial address" do
      assert Wire.decode(~s(["1","2","vehicle:x","thrust","notamap"])) ==
               {:error, "payload must be a JSON object",
                %{join_ref: "1", ref: "2", topic: "vehicle:x"}}

      for bad <- ["null", "1", "[]", "[{}]", "true", ~s("")] do
        assert {:error, "payload must be a JSON object", %{ref: "2", topic: "vehicle:x"}} =
                 Wire.decode(~s(["1","2","vehicle:x","thrust",#{bad}])),
               bad
      end
    end

    test "the first invalid field is reported" do
      assert {:error, "join_ref must be a string or null", %{join_ref: nil, ref: nil, topic: nil}} =
               Wire.decode(~s([1,2,3,4,5]))

      assert {:error, "topic must be a non-empty string", %{join_ref: nil, ref: "r", topic: nil}} =
               Wire.decode(~s([null,"r","",4,5]))
    end
  end

  describe "encode/5" do
    test "produces the v2 array" do
      assert Wire.encode("1", "2", "vehicle:a", "thrust", %{"surge" => 1}) ==
               ~s(["1","2","vehicle:a","thrust",{"surge":1}])
    end

    test "nil refs and nil values encode as null" do
      json = Wire.encode(nil, nil, "t", "e", %{a: nil, b: [nil, 1]})
      assert is_binary(json)

      assert :jiffy.decode(json, [:return_maps, {:null_term, nil}]) == [
               nil,
               nil,
               "t",
               "e",
               %{"a" => nil, "b" => [nil, 1]}
             ]

      refute json =~ "nil"
    end

    test "atom and string keys, booleans, atoms, numbers, nested maps" do
      payload = %{
        :mode => :motion,
        "gain" => 0.5,
        :on => true,
        :off => false,
        :n => -3,
        :nested => %{deep: %{list: [1, "two", %{three: 3}]}}
      }

      {:ok, %Message{payload: decoded}} = Wire.decode(Wire.encode("1", "2", "t", "e", payload))

      assert decoded == %{
               "mode" => "motion",
               "gain" => 0.5,
               "on" => true,
               "off" => false,
               "n" => -3,
               "nested" => %{"deep" => %{"list" => [1, "two", %{"three" => 3}]}}
             }
    end

    test "unicode and characters that need escaping survive a round trip" do
      s = "Ægir \"quoted\" \\ back\nline\ttab \u0001 😀 ☃"
      {:ok, m} = Wire.decode(Wire.encode(s, s, s, s, %{s => s}))
      assert m == %Message{join_ref: s, ref: s, topic: s, event: s, payload: %{s => s}}
    end

    test "large payloads come back as one binary" do
      big = String.duplicate("abc", 100_000)
      json = Wire.encode("1", "2", "t", "e", %{"big" => big, "list" => Enum.to_list(1..10_000)})
      assert is_binary(json)
      assert {:ok, %Message{payload: %{"big" => ^big}}} = Wire.decode(json)
    end

    test "terms JSON cannot express raise ArgumentError" do
      assert_raise ArgumentError, ~r/unsupported term \{1, 2\}/, fn ->
        Wire.encode("1", "2", "t", "e", %{a: {1, 2}})
      end

      assert_raise ArgumentError, ~r/invalid UTF-8/, fn ->
        Wire.encode("1", "2", "t", "e", %{a: <<0xFF>>})
      end

      assert_raise ArgumentError, ~r/unsupported object key 1/, fn ->
        Wire.encode("1", "2", "t", "e", %{1 => 2})
      end

      assert_raise ArgumentError, fn -> Wire.encode("1", "2", "t", "e", %{pid: self()}) end
    end
  end

  describe "encode_reply/5" do
    test "ok reply" do
      assert Wire.encode_reply("1", "2", "vehicle:a", :ok, %{"gain" => 0.5}) ==
               ~s(["1","2","vehicle:a","phx_reply",{"status":"ok","response":{"gain":0.5}}])
    end

    test "error reply decodes back" do
      json = Wire.encode_reply("1", "2", "vehicle:a", :error, %{reason: "not_in_control"})

      assert {:ok,
              %Message{
                join_ref: "1",
                ref: "2",
                topic: "vehicle:a",
                event: "phx_reply",
                payload: %{"status" => "error", "response" => %{"reason" => "not_in_control"}}
              }} = Wire.decode(json)
    end

    test "heartbeat reply with null join_ref and empty response" do
      assert Wire.encode_reply(nil, "5", "phoenix", :ok, %{}) ==
               ~s([null,"5","phoenix","phx_reply",{"status":"ok","response":{}}])
    end

    test "only :ok and :error are statuses" do
      assert_raise FunctionClauseError, fn -> Wire.encode_reply("1", "2", "t", :maybe, %{}) end
    end
  end

  describe "encode_broadcast/3" do
    test "null refs, same bytes every time" do
      payload = %{depth: 1.5, heading: nil}
      a = Wire.encode_broadcast("vehicle:a", "telemetry", payload)
      assert a == Wire.encode_broadcast("vehicle:a", "telemetry", payload)

      assert {:ok,
              %Message{
                join_ref: nil,
                ref: nil,
                topic: "vehicle:a",
                event: "telemetry",
                payload: %{"depth" => 1.5, "heading" => nil}
              }} = Wire.decode(a)
    end
  end

  # Properties (PropEr)

  defp check(property, numtests \\ 1000) do
    result = :proper.quickcheck(property, [:quiet, {:numtests, numtests}])
    assert result == true, "property failed, counterexample: #{inspect(:proper.counterexample())}"
  end

  defp let(gen, fun), do: :proper_types.bind(gen, fun, false)

  # Byte soup biased towards JSON tokens, so that it reaches the shape checks.
  defp json_soup do
    token =
      :proper_types.oneof([
        :proper_types.binary(),
        :proper_types.elements([
          "[",
          "]",
          "{",
          "}",
          ",",
          ":",
          "\"",
          "\\",
          "\\u",
          "null",
          "true",
          "1",
          "-0.5e3",
          "1e999",
          ~s("t"),
          ~s(""),
          ~s("phx_join"),
          " ",
          <<0xFF>>,
          <<0xC3>>,
          "😀"
        ])
      ])

    let(:proper_types.list(token), &IO.iodata_to_binary/1)
  end

  # Well-formed JSON of any shape (most of it not a valid frame).
  defp json_value do
    leaf = Neptunus.Test.Properties.json_leaf()

    array = :proper_types.list(leaf)
    object = let(:proper_types.list({:proper_unicode.utf8(), leaf}), &Map.new/1)

    frame_like =
      :proper_types.fixed_list([leaf, leaf, leaf, leaf, :proper_types.oneof([object, leaf])])

    let(:proper_types.oneof([leaf, array, object, frame_like]), &Neptunus.JSON.encode!/1)
  end

  defp decode_result_ok?({:ok, %Message{} = m}) do
    (is_nil(m.join_ref) or is_binary(m.join_ref)) and (is_nil(m.ref) or is_binary(m.ref)) and
      is_binary(m.topic) and m.topic != "" and is_binary(m.event) and m.event != "" and
      is_map(m.payload)
  end

  defp decode_result_ok?({:error, reason, %{join_ref: j, ref: r, topic: t} = partial})
       when is_binary(reason) and map_size(partial) == 3 do
    reason != "" and String.valid?(reason) and (is_nil(j) or is_binary(j)) and
      (is_nil(r) or is_binary(r)) and (is_nil(t) or (is_binary(t) and t != ""))
  end

  defp decode_result_ok?(_other), do: false

  test "property: decode never raises on arbitrary binaries" do
    check(:proper.forall(:proper_types.binary(), &decode_result_ok?(Wire.decode(&1))))
  end

  test "property: decode never raises on JSON-like byte soup" do
    check(:proper.forall(json_soup(), &decode_result_ok?(Wire.decode(&1))))
  end

  test "property: decode never raises on well-formed JSON of any shape" do
    check(:proper.forall(json_value(), &decode_result_ok?(Wire.decode(&1))))
  end

  defp ref_gen, do: :proper_types.oneof([:proper_types.exactly(nil), :proper_unicode.utf8()])
  defp name_gen, do: :proper_types.non_empty(:proper_unicode.utf8())

  defp payload_gen do
    value =
      :proper_types.oneof([
        :proper_unicode.utf8(),
        :proper_types.integer(),
        :proper_types.largeint(),
        :proper_types.boolean(),
        :proper_types.exactly(nil)
      ])

    let(:proper_types.list({:proper_unicode.utf8(), value}), &Map.new/1)
  end

  test "property: encode/decode round trip" do
    frame = :proper_types.tuple([ref_gen(), ref_gen(), name_gen(), name_gen(), payload_gen()])

    check(
      :proper.forall(frame, fn {join_ref, ref, topic, event, payload} ->
        Wire.decode(Wire.encode(join_ref, ref, topic, event, payload)) ==
          {:ok,
           %Message{join_ref: join_ref, ref: ref, topic: topic, event: event, payload: payload}}
      end)
    )
  end

  test "property: reply and broadcast round trip" do
    gen = :proper_types.tuple([ref_gen(), ref_gen(), name_gen(), name_gen(), payload_gen()])

    check(
      :proper.forall(gen, fn {join_ref, ref, topic, event, payload} ->
        {:ok, reply} = Wire.decode(Wire.encode_reply(join_ref, ref, topic, :error, payload))
        {:ok, bcast} = Wire.decode(Wire.encode_broadcast(topic, event, payload))

        reply == %Message{
          join_ref: join_ref,
          ref: ref,
          topic: topic,
          event: "phx_reply",
          payload: %{"status" => "error", "response" => payload}
        } and
          bcast == %Message{join_ref: nil, ref: nil, topic: topic, event: event, payload: payload}
      end),
      300
    )
  end
end
