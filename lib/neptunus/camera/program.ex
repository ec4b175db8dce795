defmodule Neptunus.Camera.Program do
  @moduledoc """
  The camera port program (`priv/neptunus_camera`, c_src/neptunus_camera.c) from the VM's
  side: where it is, opening it, writing to it and closing it. Its messages (`{:packet, 4}`
  frames, a tag byte first: `d` output, `e` an error line, `t` a picture's time, `x` the
  program's end) are read by its users — the vehicle's camera and the dive export.

  A write to a program that has just ended fails (the port is closed: its end comes next, as
  `x` or the exit status), and is not an error of the writer's.
  """

  @doc "The port program's path."
  @spec executable() :: String.t()
  def executable, do: Application.app_dir(:neptunus, "priv/neptunus_camera")

  @doc "Opens `executable` (the port program, or a stand-in) with `args`, linked to the caller."
  @spec open(String.t(), [String.t()]) :: port()
  def open(executable \\ executable(), args) do
    Port.open({:spawn_executable, executable}, [
      :binary,
      {:packet, 4},
      :exit_status,
      :use_stdio,
      args: args
    ])
  end

  @doc "Writes `message` (a tagged frame); false when the program has just ended."
  @spec tell(port(), iodata()) :: boolean()
  def tell(port, message) do
    Port.command(port, message)
  rescue
    ArgumentError -> false
  end

  @doc "Acknowledges `bytes` of `d` output (the program's flow control)."
  @spec ack(port(), non_neg_integer()) :: boolean()
  def ack(port, bytes), do: tell(port, <<?a, bytes::32>>)

  @doc """
  Closes the port (if it is still open) and drops what it said that was not read: nothing
  of it is left in the caller's mailbox.
  """
  @spec close(port()) :: :ok
  def close(port) do
    try do
      Port.close(port)
    rescue
      ArgumentError -> :ok
    end

    flush(port)
  end

  defp flush(port) do
    receive do
      {^port, _} -> flush(port)
    after
      0 -> :ok
    end
  end
end
