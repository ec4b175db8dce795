defmodule Neptunus.Position.UGPS do
  @moduledoc """
  The driver of a Water Linked Underwater GPS: a client of the topside's HTTP API
  (`Neptunus.Protocol.UnderwaterGPS`, through OTP's `:httpc`) reporting to the vehicle's
  navigation (`Neptunus.Position.Source`).

    * Every `poll_ms` (default #{250} ms) it reads the acoustic position
      (`GET /api/v1/position/acoustic/filtered`, one request at a time). A fix is new when its
      body differs from the last one read (the topside serves its latest fix until the next);
      it goes to navigation as a reading in north and east (`rotation`, the topside's
      orientation) made `latency` s before it was read (`Neptunus.Position.Reading.ugps/3`).
      A body that cannot be read, or an HTTP error status, is `{:garbage, reason}`; a request
      that fails (refused, timed out) takes the link down (`{:link, {:down, reason}}`) until
      one succeeds.
    * Every `depth_ms` (default #{500} ms) it sends the vehicle's depth estimate and the water
      temperature (`PUT /api/v1/external/depth`), as the API asks: a Locator-A1 system gives
      no position without it. The temperature is the board's (`temperature` in its samples)
      where it has one, else 10 °C; nothing is sent while there is no depth estimate.

  Options: `:id`, `:name` (default `:usbl`), `:url` (the topside's base URL, or
  `:endpoint`, a function returning it when a request is made), `:rotation` (rad),
  `:latency` (s), `:poll_ms`, `:depth_ms`, `:timeout_ms` (per request, default 1500).
  """
  use GenServer

  require Logger

  alias Neptunus.Position.{Reading, Source}
  alias Neptunus.Protocol.UnderwaterGPS

  @behaviour Source

  @poll_ms 250
  @depth_ms 500
  @default_temperature 10.0

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{}
    @enforce_keys [:id, :name, :endpoint, :reading, :poll_ms, :depth_ms, :timeout_ms]
    defstruct [
      :id,
      :name,
      :endpoint,
      :reading,
      :poll_ms,
      :depth_ms,
      :timeout_ms,
      :poll_request,
      :depth_request,
      :last_body,
      link: :unknown
    ]
  end

  @impl Source
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts), do: Source.start_server(__MODULE__, opts, :usbl)

  # Callbacks

  @impl true
  def init(opts) do
    endpoint = Source.endpoint(opts, fn -> Keyword.fetch!(opts, :url) end)

    state = %State{
      id: Keyword.fetch!(opts, :id),
      name: Keyword.fetch!(opts, :name),
      endpoint: endpoint,
      reading: Keyword.take(opts, [:rotation, :latency]),
      poll_ms: Keyword.get(opts, :poll_ms, @poll_ms),
      depth_ms: Keyword.get(opts, :depth_ms, @depth_ms),
      timeout_ms: Keyword.get(opts, :timeout_ms, 1_500)
    }

    send(self(), :poll)
    send(self(), :depth)
    {:ok, state}
  end

  @impl true
  def handle_info(:poll, state) do
    Process.send_after(self(), :poll, state.poll_ms)

    if state.poll_request do
      {:noreply, state}
    else
      case request(state, :get, UnderwaterGPS.acoustic_path(), nil) do
        {:ok, ref} -> {:noreply, %{state | poll_request: ref}}
        {:error, reason} -> {:noreply, down(state, describe(reason), Source.now())}
      end
    end
  end

  def handle_info(:depth, state) do
    Process.send_after(self(), :depth, state.depth_ms)

    case {state.depth_request, vehicle_depth(state.id)} do
      {nil, {depth, temperature}} when is_number(depth) ->
        body = UnderwaterGPS.encode_depth(depth, temperature || @default_temperature)

        case request(state, :put, UnderwaterGPS.depth_path(), body) do
          {:ok, ref} -> {:noreply, %{state | depth_request: ref}}
          {:error, reason} -> {:noreply, down(state, describe(reason), Source.now())}
        end

      _ ->
        {:noreply, state}
    end
  end

  def handle_info({:http, {ref, result}}, %State{poll_request: ref} = state) do
    now = Source.now()
    state = %{state | poll_request: nil}

    case result do
      {{_, 200, _}, _headers, body} ->
        {:noreply, state |> up(now) |> fix(body, now)}

      {{_, status, reason}, _headers, body} ->
        Source.report(
          state.id,
          state.name,
          {:garbage, "HTTP #{status} #{reason}: #{excerpt(body)}"},
          now
        )

        {:noreply, up(state, now)}

      {:error, reason} ->
        {:noreply, down(state, describe(reason), now)}
    end
  end

  def handle_info({:http, {ref, result}}, %State{depth_request: ref} = state) do
    now = Source.now()
    state = %{state | depth_request: nil}

    case result do
      {{_, 200, _}, _headers, body} ->
        case UnderwaterGPS.decode_operation(body) do
          :ok ->
            :ok

          {:error, reason} ->
            Logger.warning("vehicle #{state.id}: the topside refused the depth: #{reason}")
        end

        {:noreply, up(state, now)}

      {{_, status, _}, _headers, body} ->
        Logger.warning(
          "vehicle #{state.id}: the topside answered the depth with HTTP #{status}: #{excerpt(body)}"
        )

        {:noreply, up(state, now)}

      {:error, reason} ->
        {:noreply, down(state, describe(reason), now)}
    end
  end

  def handle_info(_stale, state), do: {:noreply, state}

  defp request(state, method, path, body) do
    url = String.to_charlist(state.endpoint.() <> path)
    http_opts = [timeout: state.timeout_ms, connect_timeout: state.timeout_ms]
    opts = [sync: false, body_format: :binary]

    request =
      case method do
        :get -> {url, []}
        :put -> {url, [], ~c"application/json", body}
      end

    :httpc.request(method, request, http_opts, opts)
  end

  defp fix(state, body, now) do
    if body == state.last_body do
      state
    else
      case UnderwaterGPS.decode_fix(body) do
        {:ok, fix} ->
          Source.report(state.id, state.name, Reading.ugps(fix, now, state.reading), now)

        {:error, reason} ->
          Source.report(state.id, state.name, {:garbage, reason}, now)
      end

      %{state | last_body: body}
    end
  end

  defp up(%State{link: :up} = state, _now), do: state

  defp up(state, now) do
    Source.report(state.id, state.name, {:link, :up}, now)

    Logger.info(
      "vehicle #{state.id}: Underwater GPS #{state.name} answers at #{state.endpoint.()}"
    )

    %{state | link: :up}
  end

  defp down(%State{link: {:down, reason}} = state, reason, _now), do: state

  defp down(state, reason, now) do
    Source.report(state.id, state.name, {:link, {:down, reason}}, now)
    Logger.warning("vehicle #{state.id}: Underwater GPS #{state.name}: #{reason}")
    %{state | link: {:down, reason}, last_body: nil}
  end

  defp vehicle_depth(id) do
    Neptunus.Vehicle.Navigation.water(id)
  catch
    :exit, _ -> nil
  end

  defp describe({:failed_connect, [{:to_address, _} | [{_, _, reason} | _]]}),
    do: Source.describe_error(reason)

  defp describe({:failed_connect, _}), do: "cannot connect"
  defp describe(:timeout), do: "no answer in time"
  defp describe(:socket_closed_remotely), do: "closed by the topside"
  defp describe(reason), do: Source.describe_error(reason)

  defp excerpt(body) when is_binary(body) do
    if byte_size(body) > 80, do: binary_part(body, 0, 80) <> "…", else: body
  end

  defp excerpt(_), do: ""
end
