defmodule Neptunus.Vehicle.Position do
  @moduledoc """
  A vehicle's position sources (`Neptunus.Position.Source`), one child each, as configured
  (`position:` from `Neptunus.Config.Position`):

    * `{:dvl, host, port}` — `Neptunus.Position.DVL`, source `:dvl`;
    * `{:ugps, url, rotation}` — `Neptunus.Position.UGPS`, source `:usbl`;
    * `{:sim_dvl, settings}`, `{:sim_usbl, settings}` — `Neptunus.Position.Simulated`,
      sources `:dvl` and `:usbl`;
    * `{:test, name, opts}` — `Neptunus.Position.Test` (tests).

  It sits beside the control chain in the vehicle's tree, after it: a source that fails
  restarts here and nowhere else (navigation just hears its link go down and up), and the
  control chain never waits for it.

  `command/3` sends a command to a source (`:reset_dead_reckoning`, `:calibrate_gyro` on a
  DVL).
  """
  use Supervisor

  alias Neptunus.Position.{DVL, Simulated, UGPS}

  @spec start_link(keyword()) :: Supervisor.on_start()
  def start_link(opts) do
    id = Keyword.fetch!(opts, :id)
    Supervisor.start_link(__MODULE__, opts, name: Neptunus.Fleet.via(__MODULE__, id))
  end

  @doc "The sources' names and implementations for a vehicle's `position` option."
  @spec sources([Neptunus.Config.Position.source() | tuple()]) :: [{atom(), module(), keyword()}]
  def sources(position) do
    Enum.map(position, fn
      {:dvl, host, port} -> {:dvl, DVL, [host: host, port: port]}
      {:ugps, url, rotation} -> {:usbl, UGPS, [url: url, rotation: rotation]}
      {:sim_dvl, settings} -> {:dvl, Simulated, [kind: :dvl, settings: settings]}
      {:sim_usbl, settings} -> {:usbl, Simulated, [kind: :usbl, settings: settings]}
      {:test, name, opts} -> {name, Neptunus.Position.Test, opts}
    end)
  end

  @doc """
  Sends `command` to vehicle `id`'s source `name`: the device's answer, or why not
  (`"no position source dvl on this vehicle"`, the source refusing commands).
  """
  @spec command(String.t(), atom(), atom()) :: {:ok, term()} | {:error, String.t()}
  def command(id, name, command) do
    case Enum.find(configured(id), fn {n, _module} -> n == name end) do
      nil ->
        {:error, "no position source #{name} on this vehicle"}

      {_name, module} ->
        if function_exported?(module, :command, 3),
          do: module.command(id, name, command),
          else: {:error, "position source #{name} takes no commands"}
    end
  catch
    :exit, _ -> {:error, "position source #{name} is restarting: try again"}
  end

  @doc """
  The untrusted `position_source` command (`%{"source" => "dvl", "command" =>
  "reset_dead_reckoning" | "calibrate_gyro"}`): checked here, carried out in a process of its
  own (a calibration takes up to 15 s) which calls `notify` with `:ok` or `{:error, reason}`.
  Returns at once: `:ok`, or `{:error, reason}` for a malformed command.
  """
  @spec request(String.t(), term(), (:ok | {:error, String.t()} -> term())) ::
          :ok | {:error, String.t()}
  def request(id, payload, notify) do
    with {:ok, name, command} <- validate(payload) do
      spawn(fn ->
        case command(id, name, command) do
          {:ok, _result} -> notify.(:ok)
          {:error, reason} -> notify.({:error, reason})
        end
      end)

      :ok
    end
  end

  @commands %{
    "reset_dead_reckoning" => :reset_dead_reckoning,
    "calibrate_gyro" => :calibrate_gyro
  }

  defp validate(%{"source" => source, "command" => command} = payload)
       when is_binary(source) and map_size(payload) == 2 do
    case {Map.fetch(@commands, command), known_source(source)} do
      {{:ok, command}, {:ok, name}} ->
        {:ok, name, command}

      {:error, _} ->
        {:error,
         ~s(command must be "reset_dead_reckoning" or "calibrate_gyro", got #{Neptunus.Validate.show(command)})}

      {_, :error} ->
        {:error, "no position source #{source} on this vehicle"}
    end
  end

  defp validate(payload),
    do:
      {:error,
       "position_source needs source and command (only), got #{Neptunus.Validate.show(payload)}"}

  defp known_source(source) do
    {:ok, String.to_existing_atom(source)}
  rescue
    ArgumentError -> :error
  end

  defp configured(id) do
    Neptunus.Fleet.via(__MODULE__, id)
    |> Supervisor.which_children()
    |> Enum.map(fn {{__MODULE__, name}, _pid, _type, [module]} -> {name, module} end)
  end

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)

    children =
      for {name, module, source_opts} <- sources(Keyword.get(opts, :position, [])) do
        %{
          id: {__MODULE__, name},
          start: {module, :start_link, [[id: id, name: name] ++ source_opts]},
          type: if(module == Simulated, do: :supervisor, else: :worker),
          modules: [module]
        }
      end

    Supervisor.init(children, strategy: :one_for_one, max_restarts: 10, max_seconds: 10)
  end
end
