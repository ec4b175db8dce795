defmodule Neptunus.Camera.FrameTest do
  use ExUnit.Case, async: true

  import Bitwise
  import Neptunus.Test.Properties

  alias Neptunus.Camera.{Frame, Pose}

  doctest Frame
  doctest Pose

  test "what is built parses back; the header is 28 bytes; the payload is not copied" do
    gen =
      {:proper_types.binary(), :proper_types.boolean(), :proper_types.boolean(),
       :proper_types.choose(0, 0xFFFFFFFF), :proper_types.choose(0, 0xFFFFFFFF),
       :proper_types.choose(0, 1 <<< 62)}

    check(gen, fn {payload, key?, first?, generation, seq, us} ->
      frame =
        Frame.new(:h264, payload,
          keyframe: key?,
          first: first?,
          generation: generation,
          seq: seq,
          arrival_us: us,
          capture_us: div(us, 2)
        )

      byte_size(frame.data) == Frame.header_bytes() + byte_size(payload) and
        Frame.parse(frame.data) ==
          {:ok,
           %{
             kind: :h264,
             keyframe: key?,
             first: first?,
             generation: generation,
             seq: seq,
             arrival_us: us,
             capture_us: div(us, 2),
             payload: payload
           }} and Frame.payload(frame) == payload
    end)

    assert Frame.parse(<<2, 1, 0>>) == {:error, "not a version 1 video frame"}
  end

  test "a pose for the renderer: p and 15 big-endian doubles" do
    pose =
      Pose.new(
        %{x: 1, y: 2, z: 3, phi: 4, theta: 5, psi: 6, u: 7, v: 8, w: 9, p: 10, q: 11, r: 12},
        %{lights: 255, laser: 0, tilt: 0.5}
      )

    assert <<?p, values::binary>> = Pose.encode(pose)

    assert for(<<x::float-64 <- values>>, do: x) ==
             Enum.map(1..12, &(&1 * 1.0)) ++ [1.0, 0.0, 0.5]
  end
end
