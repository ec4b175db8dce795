defmodule Neptunus.JSONTest do
  use ExUnit.Case, async: true

  alias Neptunus.JSON
  alias Neptunus.Test.Properties

  doctest JSON

  describe "decode/2" do
    test "accepts any JSON value, not only objects" do
      assert JSON.decode("42") == {:ok, 42}
      assert JSON.decode(~s({"a":null})) == {:ok, %{"a" => nil}}
      assert JSON.decode(~s(["x", true]), copy_strings: true) == {:ok, ["x", true]}
    end

    test "reports errors a person can read" do
      assert JSON.decode("") == {:error, "empty JSON input"}
      assert JSON.decode("{") == {:error, "invalid JSON at byte 2: unexpected end of input"}

      assert JSON.decode("[tru]") ==
               {:error, "invalid JSON at byte 2: invalid literal (expected true, false or null)"}

      assert JSON.decode("[1] x") ==
               {:error, "invalid JSON at byte 5: unexpected data after the JSON value"}

      assert JSON.decode("1.5e400") == {:error, "invalid JSON: number out of range"}

      assert JSON.decode(<<"\"", 0xFE, "\"">>) ==
               {:error, "invalid JSON at byte 2: invalid string (bad escape or invalid UTF-8)"}

      assert JSON.decode(:nope) == {:error, "JSON input must be a binary"}
    end
  end

  describe "encode!/1" do
    test "round trip of any JSON value" do
      for term <- [nil, true, 1, -2.5, "s", [], [1, [2, [nil]]], %{"a" => %{"b" => []}}] do
        assert JSON.decode(JSON.encode!(term)) == {:ok, term}
      end
    end

    test "atoms encode as strings" do
      assert JSON.encode!(%{status: :ok}) == ~s({"status":"ok"})
    end

    test "raises ArgumentError on terms JSON cannot express" do
      assert_raise ArgumentError, ~r/unsupported term \{1, 2\}/, fn ->
        JSON.encode!(%{a: {1, 2}})
      end

      assert_raise ArgumentError, ~r/invalid UTF-8 string/, fn -> JSON.encode!(<<0xFF>>) end
      assert_raise ArgumentError, ~r/unsupported object key/, fn -> JSON.encode!(%{{1} => 1}) end
    end
  end

  test "property: decode never raises and always explains" do
    Properties.check(:proper_types.binary(), fn bin ->
      case JSON.decode(bin) do
        {:ok, _} -> true
        {:error, reason} -> is_binary(reason) and reason != ""
      end
    end)
  end

  test "property: encode! then decode gives the value back" do
    leaf = Properties.json_leaf()

    object = Properties.bind(:proper_types.list({:proper_unicode.utf8(), leaf}), &Map.new/1)
    value = :proper_types.oneof([leaf, :proper_types.list(leaf), object])

    Properties.check(value, &(JSON.decode(JSON.encode!(&1)) == {:ok, &1}))
  end
end
