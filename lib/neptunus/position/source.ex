defmodule Neptunus.Position.Source do
  @moduledoc """
  A position source of a vehicle: the behaviour every source implements, like the boards'
  (`Neptunus.Vehicle.Board`), and the API the rest of the vehicle uses.

  A source process is started by `Neptunus.Vehicle.Position` with `id` (the vehicle) and
  `name` (the source's name in navigation: `:dvl`, `:usbl`, …), registered as
  `via(id, name)`, and reports to navigation with `report/4` —
  `Neptunus.Navigation.Position`'s reports: readings (measurements with the time they were
  made), its link going up or down, and what it could not read (`{:garbage, reason}`).

  Implementations:

    * `Neptunus.Position.DVL` — a Water Linked DVL over its TCP JSON protocol;
    * `Neptunus.Position.UGPS` — a Water Linked Underwater GPS over its HTTP API;
    * `Neptunus.Position.Simulated` — the simulator's DVL or USBL served on loopback over
      those protocols, read by the two drivers above (a simulated vehicle's sources);
    * `Neptunus.Position.Test` — a test double: the test says what it reports.

  Optional: `command/3` — a command for the device (`:reset_dead_reckoning`,
  `:calibrate_gyro` for a DVL); sources without it refuse commands.
  """

  @doc "Starts the source (options include `:id` and `:name`); must register under `via/2`."
  @callback start_link(keyword()) :: GenServer.on_start()

  @doc "Sends a command to the device and waits for its answer."
  @callback command(id :: String.t(), name :: atom(), command :: atom()) ::
              {:ok, term()} | {:error, String.t()}

  @optional_callbacks command: 3

  @doc "The registered name of vehicle `id`'s source `name`."
  @spec via(String.t(), atom()) :: GenServer.name()
  def via(id, name), do: Neptunus.Fleet.via({__MODULE__, name}, id)

  @doc """
  Starts `module`, a GenServer source, registered under `via/2` with the options' `:id` and
  `:name` (`default_name` when they have none); `module.init/1` receives the options with
  `:name` set.
  """
  @spec start_server(module(), keyword(), atom()) :: GenServer.on_start()
  def start_server(module, opts, default_name) do
    id = Keyword.fetch!(opts, :id)
    name = Keyword.get(opts, :name, default_name)
    GenServer.start_link(module, Keyword.put(opts, :name, name), name: via(id, name))
  end

  @doc """
  Where a network source connects: the options' `:endpoint` (a function of no arguments,
  asked at each connection: a simulated device's port is known only once it listens), else
  `default` (a function reading the fixed address from the options).
  """
  @spec endpoint(keyword(), (() -> term())) :: (() -> term())
  def endpoint(opts, default) do
    case Keyword.fetch(opts, :endpoint) do
      {:ok, fun} when is_function(fun, 0) -> fun
      :error -> default
    end
  end

  @doc """
  Why a network source's link failed, as navigation says it: the socket error's text
  (`:econnrefused` is `"connection refused"`), else the reason as it is.

      iex> Neptunus.Position.Source.describe_error(:econnrefused)
      "connection refused"
      iex> Neptunus.Position.Source.describe_error(:closed)
      "closed"
      iex> Neptunus.Position.Source.describe_error({:tls, 1})
      "{:tls, 1}"
  """
  @spec describe_error(term()) :: String.t()
  def describe_error(reason) when is_atom(reason) do
    case :inet.format_error(reason) do
      ~c"unknown POSIX error" ++ _ -> Atom.to_string(reason)
      text -> List.to_string(text)
    end
  end

  def describe_error(reason), do: inspect(reason)

  @doc "Reports to vehicle `id`'s navigation (asynchronous), at monotonic `at` (s)."
  @spec report(String.t(), atom(), Neptunus.Navigation.Position.report(), float()) :: :ok
  def report(id, name, report, at),
    do: Neptunus.Vehicle.Navigation.position(id, name, report, at)

  @doc "Now, in the seconds of the position filter's clock (monotonic)."
  @spec now() :: float()
  def now, do: Neptunus.Clock.monotonic_ms() / 1000
end
