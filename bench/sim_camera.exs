# The simulated camera's cost: the renderer (priv/neptunus_camera sim) and its encoder (ffmpeg,
# libx264 ultrafast/zerolatency) on this machine, for a vehicle that moves.
#
#   bench/sim_camera [SECONDS] [WIDTHxHEIGHT] [FPS]   (defaults 20, 640x360, 30)
#
# Run through bench/sim_camera (MIX_ENV=prod mix run --no-start bench/sim_camera.exs). Prints
# figures, never asserts. Runs the port program exactly as the vehicle's camera does
# (Neptunus.Camera.Source.command/2), feeds it a pose at 100 Hz (the simulator's rate) and cuts
# its output into frames (Neptunus.Camera.Stream), without the web endpoint.

Code.require_file("support/proc.exs", __DIR__)

defmodule Bench.SimCamera do
  alias Neptunus.Camera.{Frame, Pose, Source, Stream}

  @warmup_ms 2_000

  def main(args) do
    {seconds, size, fps} =
      case args do
        [s, size, fps] -> {String.to_integer(s), size, String.to_integer(fps)}
        [s, size] -> {String.to_integer(s), size, 30}
        [s] -> {String.to_integer(s), "640x360", 30}
        [] -> {20, "640x360", 30}
      end

    {:ok, source} = Source.parse("sim@#{size}@#{fps}")
    ffmpeg = System.find_executable("ffmpeg") || raise "ffmpeg is not installed (make setup)"
    camera = Path.expand("priv/neptunus_camera")
    File.exists?(camera) || raise "#{camera} is not built: MIX_ENV=prod mix compile"
    {:ok, command} = Source.command(source, %{ffmpeg: ffmpeg, camera: camera})

    IO.puts("Neptunus simulated camera benchmark — #{size} at #{fps} fps, H.264, #{seconds} s")
    IO.puts("machine: #{System.schedulers_online()} cores, load average before: #{loadavg()}\n")

    port =
      Port.open({:spawn_executable, command.executable}, [
        :binary,
        {:packet, 4},
        :exit_status,
        args: command.args
      ])

    {:os_pid, renderer} = Port.info(port, :os_pid)
    stream = Stream.new(format: :flv, source: "sim", fps: fps, generation: 1)
    :timer.send_interval(10, :pose)
    started = System.monotonic_time(:millisecond)

    # warm up, then measure
    state = %{port: port, stream: stream, t0: started, frames: [], bytes: 0, measuring: false}
    state = run(state, started + @warmup_ms)
    encoder = child(renderer)
    before = {cpu(renderer), cpu(encoder), machine(), stats(port)}

    state =
      run(
        %{state | frames: [], bytes: 0, measuring: true},
        System.monotonic_time(:millisecond) + seconds * 1000
      )

    after_ = {cpu(renderer), cpu(encoder), machine(), stats(port)}
    Port.close(port)
    report(seconds, fps, state, before, after_)
  end

  defp run(state, until) do
    left = until - System.monotonic_time(:millisecond)

    if left <= 0 do
      state
    else
      receive do
        :pose ->
          Port.command(state.port, Pose.encode(pose(state.t0)))
          run(state, until)

        {port, {:data, <<?d, bytes::binary>>}} when port == state.port ->
          Port.command(port, <<?a, byte_size(bytes)::32>>)
          {:ok, stream, out} = Stream.feed(state.stream, bytes, Neptunus.Clock.wall_us())
          frames = for {:frame, f} <- out, do: f

          run(
            %{
              state
              | stream: stream,
                frames: frames ++ state.frames,
                bytes: state.bytes + byte_size(bytes)
            },
            until
          )

        {port, {:data, <<?t, index::32, us::64>>}} when port == state.port ->
          run(%{state | stream: Stream.stamp(state.stream, index, us)}, until)

        {port, {:data, <<?e, line::binary>>}} when port == state.port ->
          IO.puts("camera program: #{line}")
          run(state, until)

        {port, {:exit_status, status}} when port == state.port ->
          raise "the camera program exited (#{status})"

        _ ->
          run(state, until)
      after
        left -> state
      end
    end
  end

  # A vehicle circling at 0.5 m/s, turning 0.2 rad/s, bobbing between 3 and 7 m, lights on.
  defp pose(t0) do
    t = (System.monotonic_time(:millisecond) - t0) / 1000
    psi = 0.2 * t

    Pose.new(
      %{
        x: 2.5 * :math.sin(psi),
        y: 2.5 * (1 - :math.cos(psi)),
        z: 5 + 2 * :math.sin(t / 5),
        phi: 0.05 * :math.sin(t),
        theta: -0.3 + 0.05 * :math.sin(t / 2),
        psi: psi,
        u: 0.5,
        v: 0.0,
        w: 0.4 * :math.cos(t / 5),
        p: 0.05 * :math.cos(t),
        q: 0.0,
        r: 0.2
      },
      %{lights: 200, laser: 255, tilt: -0.2}
    )
  end

  defp report(seconds, fps, state, {r0, e0, m0, s0}, {r1, e1, m1, s1}) do
    wall = seconds * 1.0
    renderer = (r1 - r0) / wall * 100
    encoder = (e1 - e0) / wall * 100
    frames = Enum.reverse(state.frames)
    encoded = length(frames)

    latencies =
      for f <- frames,
          {:ok, %{capture_us: c, arrival_us: a}} = Frame.parse(f.data),
          c > 0,
          do: (a - c) / 1000

    IO.puts("pictures encoded: #{encoded} (#{Float.round(encoded / wall, 1)} /s of #{fps})")

    IO.puts(
      "renderer: #{s1.rendered - s0.rendered} rendered, #{s1.skipped - s0.skipped} deadlines skipped (encoder busy), mean render #{s1.render_us} µs CPU"
    )

    IO.puts(
      "bitrate: #{Float.round(state.bytes * 8 / wall / 1000, 0)} kbit/s, keyframes: #{Enum.count(frames, & &1.keyframe)}"
    )

    IO.puts(
      "render → cut from the encoder's output: p50 #{pct(latencies, 50)} ms, p99 #{pct(latencies, 99)} ms"
    )

    IO.puts(
      "CPU, % of one core: renderer #{f1(renderer)}, encoder (ffmpeg) #{f1(encoder)}, together #{f1(renderer + encoder)} (budget 25)"
    )

    rendered = max(s1.rendered - s0.rendered, 1)
    per_picture = (r1 - r0 + e1 - e0) / rendered * 1000

    IO.puts(
      "CPU per picture (renderer + encoder): #{f1(per_picture)} ms; at #{fps} fps that is " <>
        "#{f1(per_picture * fps / 10)} % of one core"
    )

    {busy, total} = {m1.busy - m0.busy, m1.total - m0.total}

    IO.puts(
      "machine: CPU busy #{f1(busy / max(total, 1) * 100)} % of all cores during the run, load average after: #{loadavg()}"
    )
  end

  defp pct([], _), do: "n/a"

  defp pct(values, p) do
    sorted = Enum.sort(values)
    sorted |> Enum.at(min(length(sorted) - 1, round(p / 100 * (length(sorted) - 1)))) |> f1()
  end

  defp f1(x), do: :erlang.float_to_binary(x * 1.0, decimals: 1)

  defp stats(port) do
    Port.command(port, "s")

    receive do
      {^port, {:data, <<?s, text::binary>>}} ->
        text
        |> String.split()
        |> Map.new(fn kv ->
          [k, v] = String.split(kv, "=")
          {String.to_atom(k), String.to_integer(v)}
        end)
    after
      10_000 -> raise "no counters from the camera program"
    end
  end

  # the OS pid of the renderer's child (ffmpeg)
  defp child(pid) do
    case File.read("/proc/#{pid}/task/#{pid}/children") do
      {:ok, text} -> text |> String.split() |> hd() |> String.to_integer()
      _ -> raise "no encoder process under the renderer"
    end
  end

  # CPU seconds (user + system) of an OS process and its threads
  defp cpu(pid), do: Bench.Proc.cpu_ticks(pid) / 100

  defp machine do
    {busy, total} = Bench.Proc.machine_ticks()
    %{busy: busy, total: total}
  end

  defp loadavg, do: Bench.Proc.loadavg()
end

Bench.SimCamera.main(System.argv())
