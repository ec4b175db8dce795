defmodule Neptunus.ConfigTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Config

  alias Neptunus.Config

  describe "endpoint!/2" do
    test "defaults" do
      assert Config.endpoint!(%{}, 4102) == %{port: 4102, bind: {127, 0, 0, 1}}
    end

    test "IPv6 bind" do
      assert %{bind: {0, 0, 0, 0, 0, 0, 0, 1}} = Config.endpoint!(%{"NEPTUNUS_BIND" => "::1"}, 1)
    end

    for bad <- ["", "abc", "0", "65536", "80.5", "-1", "4000x"] do
      test "port #{inspect(bad)} is refused with the variable named" do
        assert_raise ArgumentError, ~r/NEPTUNUS_PORT=.*TCP port number/, fn ->
          Config.endpoint!(%{"NEPTUNUS_PORT" => unquote(bad)}, 4000)
        end
      end
    end

    test "bad bind address" do
      assert_raise ArgumentError, ~r/NEPTUNUS_BIND="localhost:80".*IP address/, fn ->
        Config.endpoint!(%{"NEPTUNUS_BIND" => "localhost:80"}, 4000)
      end
    end
  end

  describe "vehicles!/1" do
    test "default is one simulated vehicle" do
      assert Config.vehicles!(%{}) == [%{id: "neptunus-1", board: :simulated}]
    end

    test "several vehicles, whitespace tolerated" do
      assert [%{id: "a"}, %{id: "b_2"}] =
               Config.vehicles!(%{"NEPTUNUS_VEHICLES" => " a=simulated ,b_2= simulated"})
    end

    for {bad, message} <- [
          {"", ~r/at least one vehicle|id=board/},
          {"rov", ~r/id=board pairs/},
          {"rov=warp", ~r/known board.*simulated/},
          {"=simulated", ~r/vehicle ids/},
          {"a b=simulated", ~r/vehicle ids/},
          {"a=simulated,a=simulated", ~r/unique vehicle ids/},
          {String.duplicate("x", 33) <> "=simulated", ~r/vehicle ids/},
          {"a=simulated,", ~r/id=board pairs/}
        ] do
      test "refuses #{inspect(bad)}" do
        assert_raise ArgumentError, unquote(Macro.escape(message)), fn ->
          Config.vehicles!(%{"NEPTUNUS_VEHICLES" => unquote(bad)})
        end
      end
    end
  end
end
