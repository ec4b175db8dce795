defmodule Neptunus.ValidateTest do
  use ExUnit.Case, async: true

  alias Neptunus.Validate, as: V

  doctest V

  test "object/4 names the missing field with its path" do
    assert V.object(%{}, "events[1]", ["t"]) == {:error, "missing field: events[1].t"}
    assert V.object([], "thrust", ["surge"]) == {:error, "thrust must be an object, got []"}
  end

  test "numbers, booleans, strings and integers name the field and show the value as JSON" do
    assert V.number(1, "gain") == {:ok, 1.0}
    assert V.number("x", "gain") == {:error, "gain must be a number, got \"x\""}
    assert V.boolean(nil, "on") == {:error, "on must be true or false, got null"}
    assert V.string(1, "name") == {:error, "name must be a string, got 1"}
    assert V.integer(1.5, "n") == {:error, "n must be an integer, got 1.5"}
  end

  test "show/1 cuts long values and falls back to inspect for terms JSON cannot express" do
    assert V.show(%{"a" => nil}) == ~s({"a":null})
    assert String.length(V.show(String.duplicate("x", 200))) <= 63
    assert V.show({1, 2}) == "{1, 2}"
  end
end
