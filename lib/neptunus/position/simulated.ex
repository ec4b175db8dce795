defmodule Neptunus.Position.Simulated do
  @moduledoc """
  A simulated vehicle's position source: the simulator's device served on loopback
  (`Neptunus.Sim.DVLServer` or `Neptunus.Sim.UGPSServer`) and the real driver reading it
  (`Neptunus.Position.DVL` or `Neptunus.Position.UGPS`), under one `:rest_for_one`
  supervisor: the driver asks the server where it listens each time it connects, and a
  restarted server (a new port) restarts the driver.

  Options: `:id`, `:name`, `:kind` (`:dvl` or `:usbl`), `:settings` (the simulated device's,
  `Neptunus.Sim.DVL` or `Neptunus.Sim.USBL`), `:driver` (the driver's options, e.g.
  `poll_ms`).
  """
  use Supervisor

  alias Neptunus.Position.{DVL, Source, UGPS}
  alias Neptunus.Sim.{DVLServer, UGPSServer}

  @behaviour Source

  @impl Source
  @spec start_link(keyword()) :: Supervisor.on_start()
  def start_link(opts), do: Supervisor.start_link(__MODULE__, opts)

  @impl Source
  @spec command(String.t(), atom(), atom()) :: {:ok, term()} | {:error, String.t()}
  def command(id, name, command), do: DVL.command(id, name, command)

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)
    name = Keyword.fetch!(opts, :name)
    settings = Keyword.get(opts, :settings, [])
    driver = Keyword.get(opts, :driver, [])

    children =
      case Keyword.fetch!(opts, :kind) do
        :dvl ->
          [
            {DVLServer, id: id, name: name, dvl: settings},
            {DVL,
             [id: id, name: name, endpoint: fn -> {{127, 0, 0, 1}, DVLServer.port(id, name)} end] ++
               driver}
          ]

        :usbl ->
          [
            {UGPSServer, id: id, name: name, usbl: settings},
            {UGPS, [id: id, name: name, endpoint: fn -> UGPSServer.url(id, name) end] ++ driver}
          ]
      end

    Supervisor.init(children, strategy: :rest_for_one, max_restarts: 10, max_seconds: 10)
  end
end
