defmodule Neptunus.Fleet.Book do
  @moduledoc """
  The fleet's directory as one node sees it (pure): every vehicle of the cluster with its
  node, board and helm process, and whether it is reachable.

  It is fed the `:pg` events of the fleet's scope (`Neptunus.Fleet.Directory`): a vehicle's
  helm joins the group `{:vehicle, id, board}` on its node, and leaves it when it stops or
  when its node is cut off (`:pg` drops a lost node's members). A vehicle whose helm left
  while its node is still connected stopped (or its helm restarts and joins again): it is
  no longer listed, but remembered as `:gone` with its node. A vehicle whose node is **not**
  connected any more — cut off, crashed, or shut down (its vehicles stop just before it
  goes) — is `:unreachable`, so the pages say so instead of losing it silently; it is up
  again when its helm joins again (the nodes healed, or its node restarted).

  Each change returns the announcements to make on the vehicle's topic on this node:
  `{:unreachable, id, node}` and `{:reachable, id, node}`.
  """

  @enforce_keys [:entries]
  defstruct entries: %{}

  @type status :: :up | :unreachable | :gone
  @type entry :: %{
          id: String.t(),
          board: atom(),
          node: node(),
          pid: pid() | nil,
          status: status()
        }
  @type announcement :: {:unreachable | :reachable, String.t(), node()}
  @type t :: %__MODULE__{entries: %{optional(String.t()) => entry()}}

  @doc "An empty book."
  @spec new() :: t()
  def new, do: %__MODULE__{entries: %{}}

  @doc """
  The helm `pid` of vehicle `id` (`board`) joined on its node `node`. A vehicle of this node
  (`local`) wins over a remote one of the same id.
  """
  @spec join(t(), String.t(), atom(), pid(), node(), node()) :: {t(), [announcement()]}
  def join(%__MODULE__{} = book, id, board, pid, node, local) do
    entry = %{id: id, board: board, node: node, pid: pid, status: :up}

    case Map.get(book.entries, id) do
      %{node: ^local, status: :up} when node != local ->
        {book, []}

      %{status: :unreachable, node: ^node} ->
        {put(book, entry), [{:reachable, id, node}]}

      %{status: :unreachable} ->
        {put(book, entry), [{:reachable, id, node}]}

      _ ->
        {put(book, entry), []}
    end
  end

  @doc """
  The helm `pid` of vehicle `id` left; `connected?` tells whether its node is still
  connected (always true for this node).
  """
  @spec leave(t(), String.t(), pid(), boolean()) :: {t(), [announcement()]}
  def leave(%__MODULE__{} = book, id, pid, connected?) do
    case Map.get(book.entries, id) do
      %{pid: ^pid, node: node} = entry when not connected? ->
        {put(book, %{entry | pid: nil, status: :unreachable}), [{:unreachable, id, node}]}

      %{pid: ^pid} = entry ->
        {put(book, %{entry | pid: nil, status: :gone}), []}

      _ ->
        {book, []}
    end
  end

  @doc """
  Node `node` went down: its vehicles are unreachable, those that stopped just before too
  (`:pg` reports their helms leaving as well; whichever comes first announces).
  """
  @spec nodedown(t(), node()) :: {t(), [announcement()]}
  def nodedown(%__MODULE__{} = book, node) do
    Enum.reduce(book.entries, {book, []}, fn
      {id, %{node: ^node, status: status} = entry}, {book, announced}
      when status in [:up, :gone] ->
        {put(book, %{entry | pid: nil, status: :unreachable}),
         announced ++ [{:unreachable, id, node}]}

      _, acc ->
        acc
    end)
  end

  @doc """
  This node was renamed from `old` to `new` (it became distributed after its vehicles joined:
  they joined as `nonode@nohost`): its entries now name it as it is.
  """
  @spec rename(t(), node(), node()) :: t()
  def rename(%__MODULE__{} = book, old, new) do
    entries =
      Map.new(book.entries, fn {id, e} ->
        {id, if(e.node == old, do: %{e | node: new}, else: e)}
      end)

    %{book | entries: entries}
  end

  @doc "Forgets the unreachable (and gone) vehicles of `node` (e.g. the operator removed it)."
  @spec forget(t(), node()) :: t()
  def forget(%__MODULE__{} = book, node) do
    entries =
      book.entries
      |> Enum.reject(fn {_, e} -> e.node == node and e.status != :up end)
      |> Map.new()

    %{book | entries: entries}
  end

  @doc "Vehicle `id`'s entry (up or unreachable), or nil."
  @spec lookup(t(), String.t()) :: entry() | nil
  def lookup(%__MODULE__{} = book, id) do
    case Map.get(book.entries, id) do
      %{status: :gone} -> nil
      entry -> entry
    end
  end

  @doc "Every entry up or unreachable, sorted by id."
  @spec entries(t()) :: [entry()]
  def entries(%__MODULE__{} = book) do
    book.entries |> Map.values() |> Enum.reject(&(&1.status == :gone)) |> Enum.sort_by(& &1.id)
  end

  defp put(book, entry), do: %{book | entries: Map.put(book.entries, entry.id, entry)}
end
