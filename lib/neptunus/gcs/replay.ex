defmodule Neptunus.GCS.Replay do
  @moduledoc """
  The signed streams of every ground station session of the node, for replay protection:
  each stream `{key name, system, component, link id}` and the last timestamp accepted on it
  (`Neptunus.GCS.Admission`). A public ETS table owned by this process; sessions advance a
  stream atomically (`advance/3`), so two sessions cannot both accept the same timestamp.

  The table lives as long as this process: when it restarts, the endpoints' sessions restart
  with it (`Neptunus.GCS`'s `rest_for_one`), and a stream is new again — accepted only if it
  is at most a minute behind the node's clock (`Neptunus.Protocol.MAVLink.Signing.replay/3`).
  """
  use GenServer

  alias Neptunus.Protocol.MAVLink.Signing

  @table __MODULE__

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(_opts), do: GenServer.start_link(__MODULE__, nil, name: __MODULE__)

  @doc """
  Accepts `timestamp` on `stream` if `Signing.replay/3` allows it at the node's signing time
  `now` — and records it — or says why not.
  """
  @spec advance(Neptunus.GCS.Admission.stream(), Signing.timestamp(), Signing.timestamp()) ::
          :ok | {:error, :replayed | :too_old}
  def advance(stream, timestamp, now) do
    last =
      case :ets.lookup(@table, stream) do
        [{_, last}] -> last
        [] -> nil
      end

    with :ok <- Signing.replay(last, timestamp, now) do
      recorded =
        if last == nil do
          :ets.insert_new(@table, {stream, timestamp})
        else
          # only over a smaller timestamp: a session that got there first wins
          :ets.select_replace(@table, [
            {{stream, :"$1"}, [{:<, :"$1", timestamp}], [{{{:const, stream}, timestamp}}]}
          ]) == 1
        end

      if recorded, do: :ok, else: {:error, :replayed}
    end
  end

  @impl true
  def init(nil) do
    :ets.new(@table, [
      :named_table,
      :public,
      :set,
      write_concurrency: true,
      read_concurrency: true
    ])

    {:ok, nil}
  end
end
