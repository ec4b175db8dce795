defmodule Neptunus.Position.Test do
  @moduledoc """
  A test double of a position source (`Neptunus.Position.Source`): it reports what the test
  tells it to (`report/3`, stamped with the time it is sent) and sends every command it gets
  to the test process (`{:position_command, name, command}`), answering it with `reply`
  (default `{:ok, nil}`).

  Options: `:id`, `:name`, `:test` (the pid told of commands, default the starter), `:reply`.
  """
  use GenServer

  alias Neptunus.Position.Source

  @behaviour Source

  @impl Source
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    opts = Keyword.put_new(opts, :test, self())
    id = Keyword.fetch!(opts, :id)
    GenServer.start_link(__MODULE__, opts, name: Source.via(id, Keyword.fetch!(opts, :name)))
  end

  @doc "Makes source `name` of vehicle `id` report `report` (a `Neptunus.Navigation.Position` report)."
  @spec report(String.t(), atom(), Neptunus.Navigation.Position.report()) :: :ok
  def report(id, name, report), do: GenServer.call(Source.via(id, name), {:report, report})

  @impl Source
  @spec command(String.t(), atom(), atom()) :: {:ok, term()} | {:error, String.t()}
  def command(id, name, command), do: GenServer.call(Source.via(id, name), {:command, command})

  @impl true
  def init(opts), do: {:ok, Map.new(Keyword.take(opts, [:id, :name, :test, :reply]))}

  @impl true
  def handle_call({:report, report}, _from, state) do
    :ok = Source.report(state.id, state.name, report, Source.now())
    {:reply, :ok, state}
  end

  def handle_call({:command, command}, _from, state) do
    send(state.test, {:position_command, state.name, command})
    {:reply, Map.get(state, :reply, {:ok, nil}), state}
  end
end
