defmodule Neptunus.Vehicle.Board.OpenROV.SITL do
  @moduledoc """
  Software in the loop: the simulator behind a pseudo-terminal speaking the OpenROV serial
  protocol, driven by the real board link. `NEPTUNUS_VEHICLES=rov=sitl`.

  This is the board of a SITL vehicle — a supervisor (`:one_for_one`) with

    1. `Neptunus.Vehicle.Board.OpenROV.SITL.Device` — the simulated board: a `Neptunus.Sim`, the
       OpenROV firmware behaviour, and the master end of a pty pair (created by the port
       program, `neptunus_uart pty LINK`);
    2. `Neptunus.Vehicle.Board.OpenROV.UART` — the same board link a real vehicle uses, on the
       pty's slave end (`LINK`), registered as the vehicle's board (`Board.via(id)`).

  So everything from `Vehicle.Control` down — wiring, `go()` bytes, the port program, line
  framing, parsing, wild-point rejection, link handling, deadman pings — runs exactly as with
  hardware. `:one_for_one`: if the device dies it comes back with a new pty at the same path
  and the board link sees a hangup and reopens, as with a board that resets.

  `LINK` is `<tmp>/neptunus-<os pid>/sitl-<id>.tty` unless given as `:link` (per OS process,
  so several nodes or test runs on one machine never share a pty).

  Options: those of `Board.OpenROV.UART` (`:wiring`, `:firmware`, `:ping_interval`, …) and of
  `SITL.Device` (`:wiring`, `:firmware`, `:sim_hz` as its `:hz`, `:deadman_ms`, `:arm_ms`,
  `:loop_ms`, `:stall_ms`, `:setup_ms`, `:bootloader_ms`, `:reset_on_open` — a board that
  reboots into its bootloader whenever the line opens, as a USB Arduino —, `:initial`,
  `:sim`), `:os_time_slice_ns` to both;
  `:link`. `:firmware` (`:openrov_25` or
  `:openrov_30`) goes to both: the board link frames its commands for it and the simulated
  board behaves like it.
  """
  use Supervisor

  alias Neptunus.Vehicle.Board
  alias Neptunus.Vehicle.Board.OpenROV.UART

  @behaviour Board

  @device_opts [:wiring, :deadman_ms, :os_time_slice_ns, :initial, :sim, :firmware] ++
                 [:arm_ms, :loop_ms, :stall_ms, :setup_ms, :bootloader_ms, :reset_on_open]
  @uart_opts [
    :wiring,
    :os_time_slice_ns,
    :firmware,
    :ping_interval,
    :keepalive_timeout,
    :reopen_min,
    :reopen_max,
    :max_line,
    :confirm_retry,
    :confirm_attempts
  ]

  @impl Board
  @spec start_link(keyword()) :: Supervisor.on_start()
  def start_link(opts), do: Supervisor.start_link(__MODULE__, opts)

  @doc "The default pty link path of vehicle `id`."
  @spec link_path(String.t()) :: String.t()
  def link_path(id),
    do: Path.join([System.tmp_dir!(), "neptunus-#{System.pid()}", "sitl-#{id}.tty"])

  @impl Board
  @spec capabilities(keyword()) :: Board.capabilities()
  def capabilities(opts), do: UART.capabilities(opts)

  @doc """
  Those of `Board.OpenROV.UART`, a bootloader (`NEPTUNUS_SITL_BOOTLOADER`), and the simulator's
  camera and position sources: its vehicle lives in `Neptunus.Sim`.
  """
  @impl Board
  @spec settings() :: [Board.setting()]
  def settings, do: UART.settings() ++ [:bootloader, :sim_sources]

  @impl Board
  @spec go(String.t(), Neptunus.Allocation.thrusters()) :: :ok
  def go(id, thrusters), do: UART.go(id, thrusters)

  @impl Board
  @spec link_details() :: [atom()]
  def link_details, do: UART.link_details()

  @impl Board
  @spec keepalive(String.t()) :: :ok
  def keepalive(id), do: UART.keepalive(id)

  @impl Board
  @spec link_status(String.t()) :: map()
  def link_status(id), do: UART.link_status(id)

  @impl Board
  @spec lights(String.t(), 0..255) :: :ok
  def lights(id, n), do: UART.lights(id, n)

  @impl Board
  @spec laser(String.t(), 0..255) :: :ok
  def laser(id, n), do: UART.laser(id, n)

  @impl Board
  @spec tilt(String.t(), number()) :: :ok
  def tilt(id, rad), do: UART.tilt(id, rad)

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)
    link = Keyword.get(opts, :link) || link_path(id)

    children = [
      {Board.OpenROV.SITL.Device,
       [id: id, link: link] ++ device_hz(opts) ++ Keyword.take(opts, @device_opts)},
      {UART, [id: id, device: link, baud: 115_200] ++ Keyword.take(opts, @uart_opts)}
    ]

    Supervisor.init(children, strategy: :one_for_one, max_restarts: 10, max_seconds: 10)
  end

  # the vehicle's `:sim_hz` is the device's integration rate
  defp device_hz(opts) do
    case Keyword.fetch(opts, :sim_hz) do
      {:ok, hz} -> [hz: hz]
      :error -> []
    end
  end
end
