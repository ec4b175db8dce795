defmodule Neptunus.Protocol.WaterLinkedDVLTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Protocol.WaterLinkedDVL

  import Neptunus.Test.Properties

  alias Neptunus.Protocol.WaterLinkedDVL, as: DVL

  # the published example of a velocity report (json_v3), as the DVL sends it on one line
  @example ~s({"time": 106.3935775756836, "vx": -3.713480691658333e-05, ) <>
             ~s("vy": 5.703703573090024e-05, "vz": 2.4990416932269e-05, ) <>
             ~s("fom": 0.00016016385052353144, "covariance": [[2.4471841442164077e-08, ) <>
             ~s(-3.3937477272871774e-09, -1.6659699175747278e-09], [-3.3937477272871774e-09, ) <>
             ~s(1.4654466085062268e-08, 4.0409570134514183e-10], [-1.6659699175747278e-09, ) <>
             ~s(4.0409570134514183e-10, 1.5971971523143225e-09]], "altitude": 0.4949815273284912, ) <>
             ~s("transducers": [{"id": 0, "velocity": 0.00010825289791682735, "distance": 0.5568, ) <>
             ~s("rssi": -30.49, "nsd": -88.73, "beam_valid": true}, {"id": 1, "velocity": -1.47e-05, ) <>
             ~s("distance": 0.5664, "rssi": -31.09, "nsd": -89.51, "beam_valid": true}], ) <>
             ~s("velocity_valid": true, "status": 0, "format": "json_v3", "type": "velocity", ) <>
             ~s("time_of_validity": 1638191471563017, "time_of_transmission": 1638191471752336})

  test "the published velocity report decodes with every field" do
    assert {:ok, {:velocity, v}} = DVL.decode(@example)
    assert_in_delta v.vx, -3.713480691658333e-05, 1.0e-15
    assert v.valid
    assert v.tracking == :bottom
    assert v.time_of_transmission_us - v.time_of_validity_us == 189_319
    assert [[a, _, _], _, _] = v.covariance
    assert_in_delta a, 2.4471841442164077e-08, 1.0e-20
    assert [%{id: 0, beam_valid: true}, %{id: 1}] = v.transducers
    assert_in_delta v.time_ms, 106.39, 0.01
  end

  test "a dead-reckoning report decodes with its angles in radians" do
    line =
      ~s({"ts": 49056.809, "x": 12.4, "y": 64.6, "z": 1.77, "std": 0.002, "roll": 90, ) <>
        ~s("pitch": -45, "yaw": 180, "type": "position_local", "status": 0, "format": "json_v3"})

    assert {:ok, {:position_local, p}} = DVL.decode(line)
    assert {p.x, p.y, p.z} == {12.4, 64.6, 1.77}
    assert_in_delta p.roll, :math.pi() / 2, 1.0e-12
    assert_in_delta p.pitch, -:math.pi() / 4, 1.0e-12
    assert_in_delta p.yaw, :math.pi(), 1.0e-12
  end

  test "responses to commands decode, successful or not" do
    ok =
      ~s({"response_to":"reset_dead_reckoning","success":true,"error_message":"","result":null,) <>
        ~s("format":"json_v3.1","type":"response"})

    assert DVL.decode(ok) ==
             {:ok,
              {:response,
               %{to: "reset_dead_reckoning", success: true, error_message: "", result: nil}}}

    nak = DVL.encode_response("calibrate_gyro", false, "vehicle moving")

    assert {:ok, {:response, %{success: false, error_message: "vehicle moving"}}} =
             DVL.decode(nak)
  end

  test "water tracking is velocity through the water: marked, never taken for ground speed" do
    {:ok, {:velocity, v}} = DVL.decode(@example)

    assert {:ok, {:velocity, %{tracking: :water}}} =
             DVL.decode(DVL.encode_velocity(%{v | tracking: :water}))

    line =
      String.replace(
        @example,
        ~s("type": "velocity"),
        ~s("type": "velocity", "tracking_mode": "water")
      )

    assert {:ok, {:velocity, %{tracking: :water}}} = DVL.decode(line)
  end

  test "other report types are not garbage; garbage is an error naming what is wrong" do
    assert DVL.decode(~s({"type":"imu","x":1})) == {:ok, {:other, "imu"}}
    assert {:error, "invalid JSON" <> _} = DVL.decode("{\"vx\": 0.1,")
    assert {:error, "empty JSON input"} = DVL.decode("")
    assert DVL.decode("[1,2]") == {:error, "a report must be a JSON object, got [1,2]"}
    assert DVL.decode(~s({"vx": 1})) == {:error, "a report needs a type"}
    assert DVL.decode(~s({"type": 3})) == {:error, "type must be a string, got 3"}

    assert DVL.decode(~s({"type":"velocity","vx":0,"vy":0,"vz":0,"fom":0.1,"altitude":2})) ==
             {:error, "velocity report: missing field: velocity_valid"}

    assert DVL.decode(
             ~s({"type":"velocity","vx":0,"vy":0,"vz":0,"fom":-1,"altitude":2,"velocity_valid":true})
           ) == {:error, "velocity report: fom must be a number >= 0, got -1"}

    assert {:error, "velocity report: covariance[1] must be a list of 3 numbers" <> _} =
             DVL.decode(String.replace(@example, "[-3.3937477272871774e-09, ", "[\"x\", "))

    assert {:error, "velocity report: transducers[0].beam_valid must be true or false" <> _} =
             DVL.decode(
               String.replace(
                 @example,
                 ~s("beam_valid": true}, {"id": 1),
                 ~s("beam_valid": 1}, {"id": 1)
               )
             )

    assert {:error, "dead-reckoning report: missing field: std"} =
             DVL.decode(~s({"type":"position_local","ts":1,"x":0,"y":0,"z":0}))

    assert {:error, "response: success must be true or false, got \"yes\""} =
             DVL.decode(~s({"type":"response","response_to":"x","success":"yes"}))
  end

  test "commands encode as the protocol's lines and decode on the DVL's side" do
    for command <- DVL.commands() do
      line = DVL.encode_command(command)
      assert String.ends_with?(line, "\n")
      assert DVL.decode_command(line) == {:ok, Atom.to_string(command)}
    end

    assert DVL.decode_command(~s({"command":"self_destruct"})) ==
             {:ok, {:unknown, "self_destruct"}}

    assert {:error, _} = DVL.decode_command(~s({"cmd":1}))
    assert_raise ArgumentError, fn -> DVL.encode_command(:self_destruct) end
  end

  defp float, do: :proper_types.float(-100.0, 100.0)

  test "property: every velocity report the simulated DVL encodes decodes to itself" do
    beam =
      :proper_types.tuple([
        :proper_types.integer(0, 3),
        float(),
        :proper_types.float(0.0, 60.0),
        float(),
        float(),
        :proper_types.bool()
      ])

    check(
      {float(), float(), float(), :proper_types.float(0.0, 10.0), float(), :proper_types.bool(),
       :proper_types.integer(0, 4_503_599_627_370_496), :proper_types.list(beam)},
      fn {vx, vy, vz, fom, altitude, valid, tov, beams} ->
        v = %{
          vx: vx,
          vy: vy,
          vz: vz,
          fom: fom,
          covariance: [[fom * fom, 0.0, 0.0], [0.0, fom * fom, 0.0], [0.0, 0.0, fom * fom]],
          altitude: altitude,
          valid: valid,
          status: 0,
          time_ms: 125.0,
          time_of_validity_us: tov,
          time_of_transmission_us: tov + 40_000,
          tracking: :bottom,
          transducers:
            Enum.map(beams, fn {id, velocity, distance, rssi, nsd, ok} ->
              %{
                id: id,
                velocity: velocity,
                distance: distance,
                rssi: rssi,
                nsd: nsd,
                beam_valid: ok
              }
            end)
        }

        DVL.decode(DVL.encode_velocity(v)) == {:ok, {:velocity, v}}
      end,
      500
    )
  end

  test "property: every dead-reckoning report encodes and decodes back (angles within rounding)" do
    angle = :proper_types.float(-3.14, 3.14)

    check(
      {float(), float(), float(), :proper_types.float(0.0, 5.0), angle, angle, angle},
      fn {x, y, z, std, roll, pitch, yaw} ->
        p = %{ts: 12.5, x: x, y: y, z: z, std: std, roll: roll, pitch: pitch, yaw: yaw, status: 0}
        {:ok, {:position_local, q}} = DVL.decode(DVL.encode_position_local(p))

        Map.take(q, [:x, :y, :z, :std]) == Map.take(p, [:x, :y, :z, :std]) and
          Enum.all?([:roll, :pitch, :yaw], &(abs(q[&1] - p[&1]) < 1.0e-12))
      end,
      500
    )
  end

  test "property: no line of bytes makes decode raise" do
    check(
      :proper_types.binary(),
      fn bytes ->
        case DVL.decode(bytes) do
          {:ok, _} -> true
          {:error, reason} -> is_binary(reason)
        end
      end,
      1_000
    )
  end
end
