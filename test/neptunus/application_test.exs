defmodule Neptunus.ApplicationTest do
  use ExUnit.Case, async: true

  doctest Neptunus.Application

  test "vehicle_settings/1 keeps only the vehicles' settings that are set" do
    env = [sim_hz: 50, fanout_slice: 4, fanout_gap_ms: nil, recording: %{dir: nil}, vehicles: []]

    assert Neptunus.Application.vehicle_settings(env) == %{
             sim_hz: 50,
             fanout_slice: 4,
             recording: %{dir: nil}
           }

    assert Neptunus.Application.vehicle_settings([]) == %{}
  end
end
