defmodule Neptunus.Test.Vehicles do
  @moduledoc false
  # Parameter sets and ports for tests.

  alias Neptunus.Dynamics.Params

  @doc "neptunus' parameter document with changes (a function of the decoded JSON map)."
  @spec variant((map() -> map())) :: Params.t()
  def variant(fun) do
    path = Path.join(:code.priv_dir(:neptunus), "vehicles/neptunus.json")
    {:ok, map} = path |> File.read!() |> Neptunus.JSON.decode()
    {:ok, params} = map |> fun.() |> Params.from_map()
    params
  end

  @doc "A TCP port free on loopback right now."
  @spec free_port() :: :inet.port_number()
  def free_port do
    {:ok, socket} = :gen_tcp.listen(0, ip: {127, 0, 0, 1})
    {:ok, port} = :inet.port(socket)
    :gen_tcp.close(socket)
    port
  end
end
