# Shared by the benchmarks that measure CPU: what /proc says about a process and the machine.
defmodule Bench.Proc do
  @moduledoc false

  @doc "CPU time (user + system, clock ticks of 1/100 s) of OS process `pid` (or `\"self\"`)."
  def cpu_ticks(pid \\ "self") do
    fields =
      "/proc/#{pid}/stat" |> File.read!() |> String.split(") ") |> List.last() |> String.split()

    String.to_integer(Enum.at(fields, 11)) + String.to_integer(Enum.at(fields, 12))
  end

  @doc "`{busy, total}` clock ticks of the whole machine since boot (/proc/stat)."
  def machine_ticks do
    ["cpu" | values] =
      "/proc/stat" |> File.read!() |> String.split("\n") |> hd() |> String.split()

    values = Enum.map(values, &String.to_integer/1)
    idle = Enum.at(values, 3) + Enum.at(values, 4)
    total = Enum.sum(Enum.take(values, 8))
    {total - idle, total}
  end

  @doc "The load averages (1, 5, 15 min) as /proc/loadavg shows them."
  def loadavg,
    do: "/proc/loadavg" |> File.read!() |> String.split() |> Enum.take(3) |> Enum.join(" ")
end
