defmodule Neptunus.Config.Position do
  @moduledoc """
  Each vehicle's position sources, from `NEPTUNUS_POSITION` (`id=sources` pairs separated by
  commas; every id a configured vehicle), read and validated at boot with the vehicles
  (`Neptunus.Config.Vehicles`). A vehicle's sources are joined by `+`:

    * `dvl:HOST[:PORT]` — a Water Linked DVL (A50, A125) on its TCP JSON protocol (port
      16171 by default), e.g. `dvl:192.168.2.95`;
    * `ugps:URL[@ROTATION]` — a Water Linked Underwater GPS topside's HTTP API, e.g.
      `ugps:http://192.168.2.94`, optionally with the direction of the topside's `x` axis in
      degrees from north (its orientation; default 0: `x` north, `y` east);
    * `sim-dvl`, `sim-usbl` — the simulator's DVL and USBL, served over the same protocols on
      loopback so the real drivers read them (`Neptunus.Position.Simulated`); only on a
      vehicle with a simulator (`simulated` or `sitl` boards);
    * `none` — no position source.

  Default: `sim-dvl+sim-usbl` for `simulated` and `sitl` vehicles (so a simulated vehicle
  dives with a position), `none` for the others (an ArduSub vehicle's own position, its
  `LOCAL_POSITION_NED`, is used where it sends one, whatever this says). Example:
  `NEPTUNUS_POSITION=rov=dvl:192.168.2.95+ugps:http://192.168.2.94@90,sim=sim-dvl`.

  Each vehicle gets `position: [source]` with
  `{:dvl, host, port}`, `{:ugps, url, rotation_rad}`, `{:sim_dvl, []}` or `{:sim_usbl, []}`.
  """

  alias Neptunus.Config

  @var "NEPTUNUS_POSITION"

  @type source ::
          {:dvl, String.t(), 1..65_535}
          | {:ugps, String.t(), float()}
          | {:sim_dvl, keyword()}
          | {:sim_usbl, keyword()}

  @doc """
  The vehicles with their `position` sources (see the moduledoc).

      iex> [v] = Neptunus.Config.Position.position!([%{id: "a", board: :simulated}], %{})
      iex> v.position
      [{:sim_dvl, []}, {:sim_usbl, []}]

      iex> [v] = Neptunus.Config.Position.position!([%{id: "a", board: :uart}],
      ...>   %{"NEPTUNUS_POSITION" => "a=dvl:10.0.0.5+ugps:http://10.0.0.6@90"})
      iex> [{:dvl, "10.0.0.5", 16171}, {:ugps, "http://10.0.0.6", r}] = v.position
      iex> Float.round(r, 6)
      1.570796
  """
  @spec position!([map()], Config.env()) :: [map()]
  def position!(vehicles, env) do
    spec = Map.get(env, @var, "")

    configured =
      spec
      |> String.split(",", trim: true)
      |> Enum.map(&String.trim/1)
      |> Enum.reject(&(&1 == ""))
      |> Map.new(fn pair -> pair!(pair, spec, vehicles) end)

    Enum.map(vehicles, fn %{id: id, board: board} = vehicle ->
      default =
        if Neptunus.Vehicle.Board.takes?(board, :sim_sources),
          do: [{:sim_dvl, []}, {:sim_usbl, []}],
          else: []

      Map.put(vehicle, :position, Map.get(configured, id, default))
    end)
  end

  defp pair!(pair, spec, vehicles) do
    case String.split(pair, "=", parts: 2) do
      [id, text] ->
        id = String.trim(id)

        case Enum.find(vehicles, &(&1.id == id)) do
          nil -> bad!(spec, "ids of configured vehicles (no vehicle #{inspect(id)})")
          vehicle -> {id, sources!(String.trim(text), vehicle, pair, spec)}
        end

      _ ->
        bad!(spec, "id=sources pairs, e.g. rov=dvl:192.168.2.95+ugps:http://192.168.2.94")
    end
  end

  defp sources!("none", _vehicle, _pair, _spec), do: []

  defp sources!(text, vehicle, pair, spec) do
    sources =
      text
      |> String.split("+")
      |> Enum.map(&String.trim/1)
      |> Enum.map(fn source ->
        case source(source) do
          {:ok, source} -> source
          {:error, why} -> bad!(spec, "#{why} in #{inspect(pair)}")
        end
      end)

    kinds = Enum.map(sources, &elem(&1, 0))

    cond do
      kinds != Enum.uniq(kinds) ->
        bad!(spec, "each kind of source once per vehicle in #{inspect(pair)}")

      Enum.any?(kinds, &(&1 in [:sim_dvl, :sim_usbl])) and
          not Neptunus.Vehicle.Board.takes?(vehicle.board, :sim_sources) ->
        boards = :sim_sources |> Neptunus.Vehicle.Board.taking() |> Enum.map(&Atom.to_string/1)

        bad!(
          spec,
          "sim-dvl and sim-usbl on a #{Config.alternatives(boards)} vehicle " <>
            "(#{vehicle.id} is #{vehicle.board})"
        )

      true ->
        sources
    end
  end

  @doc """
  One source (see the moduledoc).

      iex> Neptunus.Config.Position.source("dvl:dvl.local:1234")
      {:ok, {:dvl, "dvl.local", 1234}}
      iex> Neptunus.Config.Position.source("ugps:ftp://x")
      {:error, "ugps needs an http:// URL"}
  """
  @spec source(String.t()) :: {:ok, source()} | {:error, String.t()}
  def source("sim-dvl"), do: {:ok, {:sim_dvl, []}}
  def source("sim-usbl"), do: {:ok, {:sim_usbl, []}}

  def source("dvl:" <> host_port) do
    case String.split(host_port, ":") do
      [host] when host != "" ->
        {:ok, {:dvl, host, 16_171}}

      [host, port] when host != "" ->
        case Integer.parse(port) do
          {p, ""} when p in 1..65_535 -> {:ok, {:dvl, host, p}}
          _ -> {:error, "the DVL's port must be in 1..65535"}
        end

      _ ->
        {:error, "dvl needs HOST or HOST:PORT"}
    end
  end

  def source("ugps:" <> rest) do
    {url, rotation} =
      case Regex.run(~r/^(.*)@(-?[0-9]+(?:\.[0-9]+)?)$/, rest) do
        [_, url, degrees] -> {url, elem(Float.parse(degrees), 0)}
        nil -> {rest, 0.0}
      end

    case URI.new(url) do
      {:ok, %URI{scheme: "http", host: host}} when is_binary(host) and host != "" ->
        if abs(rotation) <= 360,
          do: {:ok, {:ugps, String.trim_trailing(url, "/"), rotation * :math.pi() / 180}},
          else: {:error, "the topside's rotation must be in [-360, 360] degrees"}

      _ ->
        {:error, "ugps needs an http:// URL"}
    end
  end

  def source(other),
    do:
      {:error,
       "a source is dvl:HOST[:PORT], ugps:URL[@DEGREES], sim-dvl or sim-usbl (got #{inspect(other)})"}

  @spec bad!(String.t(), String.t()) :: no_return()
  defp bad!(spec, expected), do: Config.bad!(@var, spec, expected)
end
