defmodule Neptunus.Dynamics.ParamsTest do
  use ExUnit.Case, async: true

  alias Neptunus.Dynamics.Params

  doctest Neptunus.Dynamics.Thruster

  defp document(name \\ "neptunus") do
    path = Path.join(:code.priv_dir(:neptunus), "vehicles/#{name}.json")
    {:ok, map} = path |> File.read!() |> Neptunus.JSON.decode()
    map
  end

  test "the shipped parameter sets load and validate" do
    assert Params.available() == ["neptunus", "neptunus-sway", "thesis-4dof"]
    assert {:ok, %Params{name: "neptunus", dof: 6}} = Params.load("neptunus")
    assert {:ok, %Params{name: "thesis-4dof", dof: 4}} = Params.load(:thesis_4dof)
    assert Params.fetch!("neptunus") == Params.fetch!("neptunus")
  end

  test "unknown vehicles are refused with the list of available ones" do
    for name <- ["nope", "../etc/passwd", "Neptunus", ""] do
      assert {:error, message} = Params.load(name)
      assert message =~ "unknown vehicle"
      assert message =~ "available: neptunus, neptunus-sway, thesis-4dof"
    end

    assert_raise ArgumentError, ~r/unknown vehicle "nope"/, fn -> Params.fetch!("nope") end
  end

  test "a file whose name field differs from its file name is refused" do
    path = Path.join(System.tmp_dir!(), "params-#{System.unique_integer([:positive])}.json")
    File.write!(path, File.read!(Path.join(:code.priv_dir(:neptunus), "vehicles/neptunus.json")))
    on_exit(fn -> File.rm(path) end)
    assert {:error, message} = Params.load_file(path, "other")
    assert message =~ "name must match the file name \"other\""
    assert {:ok, _} = Params.load_file(path)
    assert {:error, message} = Params.load_file(path <> ".missing")
    assert message =~ "cannot read"
  end

  describe "validation names the field" do
    defp cases,
      do: [
        {&Map.delete(&1, "damping"), "missing field: damping"},
        {&Map.put(&1, "colour", "yellow"), "unknown field: colour"},
        {&Map.put(&1, "dof", 5), "dof must be 4 or 6, got 5"},
        {&Map.put(&1, "coriolis", true),
         ~s(coriolis must be "none", "rigid_body" or "full", got true)},
        {&put_in(&1, ["rigid_body", "mass"], 0), "rigid_body.mass must be a number > 0, got 0"},
        {&put_in(&1, ["rigid_body", "inertia"], [[1, 0], [0, 1]]),
         "rigid_body.inertia must be a 3x3 matrix"},
        {&put_in(&1, ["rigid_body", "inertia"], [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]),
         "rigid_body.inertia must be symmetric: [0][1] differs from [1][0]"},
        {&put_in(&1, ["rigid_body", "r_g"], [0, 0]),
         "rigid_body.r_g must be a list of 3 numbers"},
        {&Map.update!(&1, "added_mass", fn m -> List.replace_at(m, 0, [2, 0, 0, 0, 0, 1]) end),
         "added_mass must be symmetric: [0][5] differs from [5][0]"},
        {&put_in(&1, ["damping", "linear"], [1, 2, 3, 4, 5, -6]),
         "damping.linear[5] must be a number >= 0, got -6"},
        {&put_in(&1, ["damping", "quadratic"], "a lot"),
         "damping.quadratic must be a list of 6 numbers"},
        {&put_in(&1, ["restoring", "gravity"], "9.81"),
         ~s(restoring.gravity must be a number > 0, got "9.81")},
        {&Map.put(&1, "thrusters", []),
         "thrusters must be a non-empty list of thrusters, got []"},
        {&update_in(&1, ["thrusters"], fn [t | rest] -> [Map.put(t, "name", "bow") | rest] end),
         ~s(thrusters[0].name must be one of port, vertical, starboard, lateral, got "bow")},
        {&update_in(&1, ["thrusters"], fn [t | rest] -> [t, t | tl(rest)] end),
         "thrusters[1].name port is listed twice"},
        {&update_in(&1, ["thrusters"], fn [t | rest] ->
           [Map.put(t, "direction", [0, 0, 0]) | rest]
         end), "thrusters[0].direction must not be the zero vector"},
        {&update_in(&1, ["thrusters"], fn [t | rest] -> [Map.put(t, "deadband", 1) | rest] end),
         "thrusters[0].deadband must be a number in [0, 0.99], got 1"},
        {&update_in(&1, ["thrusters"], fn [t | rest] -> [Map.delete(t, "reverse") | rest] end),
         "missing field: thrusters[0].reverse"},
        {&put_in(&1, ["tether", "length"], -1), "tether.length must be a number >= 0, got -1"},
        {&put_in(&1, ["sensors", "wild_rate"], 1.5),
         "sensors.wild_rate must be a number in [0, 1], got 1.5"},
        {&(put_in(&1, ["sensors", "wild_rate"], 0.6) |> put_in(["sensors", "mixup_rate"], 0.6)),
         "sensors.wild_rate + sensors.mixup_rate must be at most 1"},
        {&put_in(&1, ["sensors", "depth"], %{"noise" => -1, "bias" => 0}),
         "sensors.depth.noise must be a number >= 0, got -1"},
        {&update_in(&1, ["sensors"], fn s -> Map.delete(s, "pitch") end),
         "missing field: sensors.pitch"},
        {&put_in(&1, ["power", "battery"], nil), "power.battery must be a number > 0, got null"},
        {&(put_in(&1, ["rigid_body", "inertia"], List.duplicate([0, 0, 0], 3))
           |> put_in(["added_mass"], List.duplicate(List.duplicate(0, 6), 6))),
         "the mass matrix M = M_RB + M_A must be positive definite"}
      ]

    test "every invalid field is refused with its path" do
      for {change, message} <- cases() do
        assert {:error, reason} = Params.from_map(change.(document()))
        assert reason =~ message
      end
    end

    test "the document must be an object" do
      assert {:error, "the document must be an object, got [1]"} = Params.from_map([1])
    end
  end

  test "roll and pitch inertia may be zero in a 4-DOF set only" do
    assert {:ok, _} = Params.from_map(document("thesis-4dof"))

    assert {:error, message} = document("thesis-4dof") |> Map.put("dof", 6) |> Params.from_map()

    assert message =~ "positive definite"
  end

  test "with_tether_length/2 changes the drag constant" do
    p = Params.fetch!("neptunus")
    assert Params.with_tether_length(p, 0).compiled.tether_k == 0.0

    assert_in_delta Params.with_tether_length(p, 20).compiled.tether_k,
                    2 * p.compiled.tether_k,
                    1.0e-12
  end
end
