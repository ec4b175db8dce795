defmodule Neptunus.Protocol.UnderwaterGPSTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Protocol.UnderwaterGPS

  import Neptunus.Test.Properties

  alias Neptunus.Protocol.UnderwaterGPS, as: UGPS

  test "the API's example of an acoustic position decodes, receivers zipped by index" do
    body =
      ~s({"position_valid": true, "receiver_distance": [0.45, 0.46], "receiver_nsd": [0.74, 0.75],) <>
        ~s( "receiver_rssi": [0.88, 0.89, 0.9], "receiver_valid": [1, 1], "std": 0.5, "x": 32.1,) <>
        ~s( "y": 11.2, "z": 10.2})

    assert {:ok, fix} = UGPS.decode_fix(body)
    assert {fix.x, fix.y, fix.z, fix.std, fix.valid} == {32.1, 11.2, 10.2, 0.5, true}
    assert length(fix.receivers) == 3
    assert %{distance: 0.45, rssi: 0.88, nsd: 0.74, valid: 1} = hd(fix.receivers)
    assert %{distance: nil, rssi: 0.9} = List.last(fix.receivers)
  end

  test "malformed fixes are errors naming the field" do
    assert UGPS.decode_fix("<html>") |> elem(1) =~ "acoustic position: invalid JSON"
    assert UGPS.decode_fix("[]") == {:error, "acoustic position: must be a JSON object, got []"}

    assert UGPS.decode_fix(~s({"x":1,"y":2,"z":3,"std":-1,"position_valid":true})) ==
             {:error, "acoustic position: std must be a number >= 0, got -1"}

    assert UGPS.decode_fix(~s({"x":1,"y":"2","z":3,"std":1,"position_valid":true})) ==
             {:error, "acoustic position: y must be a number, got \"2\""}

    assert UGPS.decode_fix(~s({"x":1,"y":2,"z":3,"std":1,"position_valid":1})) ==
             {:error, "acoustic position: position_valid must be true or false, got 1"}

    assert UGPS.decode_fix(
             ~s({"x":1,"y":2,"z":3,"std":1,"position_valid":true,"receiver_rssi":4})
           ) ==
             {:error, "acoustic position: receiver_rssi must be a list, got 4"}
  end

  test "the depth sent to the topside is within the API's ranges; the topside reads it back" do
    assert UGPS.decode_depth(UGPS.encode_depth(4.25, 9.0)) == {:ok, 4.25, 9.0}
    assert UGPS.decode_depth(UGPS.encode_depth(900, 99)) == {:ok, 500.0, 60.0}

    assert UGPS.decode_depth(~s({"depth": -1, "temp": 10})) ==
             {:error, "depth must be a number in [0, 500], got -1"}

    assert UGPS.decode_depth(~s({"depth": 1, "temp": 10, "x": 1})) |> elem(1) =~
             "unknown field: x"
  end

  test "operation answers" do
    assert UGPS.decode_operation(UGPS.encode_operation(:ok)) == :ok
    assert UGPS.decode_operation(UGPS.encode_operation({:error, "nope"})) == {:error, "nope"}
    assert {:error, "not an operation response" <> _} = UGPS.decode_operation("{}")
  end

  test "property: every fix the simulated topside encodes decodes to itself" do
    f = :proper_types.float(-300.0, 300.0)

    check(
      {f, f, :proper_types.float(0.0, 300.0), :proper_types.float(0.0, 50.0),
       :proper_types.bool()},
      fn {x, y, z, std, valid} ->
        receivers = [%{distance: 1.0, rssi: -30.0, nsd: -90.0, valid: true}]
        fix = %{x: x, y: y, z: z, std: std, valid: valid, receivers: receivers}
        UGPS.decode_fix(UGPS.encode_fix(fix)) == {:ok, fix}
      end
    )
  end

  test "property: no body makes decoding raise" do
    check(:proper_types.binary(), fn bytes ->
      match?({_, _}, UGPS.decode_fix(bytes)) and
        (UGPS.decode_operation(bytes) == :ok or match?({:error, _}, UGPS.decode_operation(bytes)))
    end)
  end
end
