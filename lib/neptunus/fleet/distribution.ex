defmodule Neptunus.Fleet.Distribution do
  @moduledoc """
  Starts distributed Erlang at boot for a node of a fleet (`Neptunus.Config.Cluster`):
  `:net_kernel.start/2` with the node's name, then its cookie (starting Erlang's port
  mapper, epmd, first when none runs). A loopback node listens for distribution on loopback
  only (`inet_dist_use_interface`, and a port mapper it starts listens there too); a node beyond loopback must
  run TLS distribution, which the VM must have been started with
  (`Neptunus.Config.Cluster.check_proto_dist/2`). Any failure stops the boot with a message
  that says what to set (and never shows the cookie).
  """

  require Logger

  alias Neptunus.Config.Cluster

  @doc "Starts distribution as `cluster` says; nil (no `NEPTUNUS_NODE`) does nothing."
  @spec start(Cluster.t() | nil) :: :ok | {:error, String.t()}
  def start(nil), do: :ok

  def start(%{node: name, names: names, cookie: cookie} = cluster) do
    with :ok <- Cluster.check_proto_dist(cluster, :init.get_argument(:proto_dist)),
         :ok <- listen_on(cluster),
         :ok <- epmd(cluster),
         :ok <- net_kernel(name, names) do
      Node.set_cookie(cookie)

      Logger.info(
        "distributed as #{node()} (#{if cluster.tls, do: "TLS", else: "TCP, loopback"}), " <>
          "cluster: #{Enum.join(cluster.cluster, ", ")}"
      )

      :ok
    end
  end

  defp listen_on(%{loopback: true, node: name}) do
    [_, host] = name |> Atom.to_string() |> String.split("@")

    interface =
      case :inet.parse_address(String.to_charlist(host)) do
        {:ok, address} -> address
        {:error, _} -> {127, 0, 0, 1}
      end

    Application.put_env(:kernel, :inet_dist_use_interface, interface)
  end

  defp listen_on(_cluster), do: :ok

  # Distribution registers with the port mapper (epmd), which a VM started without a name
  # did not start: start it (on loopback only for a loopback node) unless it runs.
  defp epmd(cluster) do
    cond do
      Node.alive?() or match?({:ok, _}, :erl_epmd.names()) ->
        :ok

      epmd = System.find_executable("epmd") ->
        args = if cluster.loopback, do: ["-daemon", "-address", "127.0.0.1"], else: ["-daemon"]

        case System.cmd(epmd, args, stderr_to_stdout: true) do
          {_, 0} -> wait_epmd(50)
          {out, status} -> {:error, "cannot start epmd (exit #{status}): #{String.trim(out)}"}
        end

      true ->
        {:error, "cannot start distribution: epmd (Erlang's port mapper) is not installed"}
    end
  end

  defp wait_epmd(0), do: {:error, "epmd was started but does not answer"}

  defp wait_epmd(tries) do
    case :erl_epmd.names() do
      {:ok, _} ->
        :ok

      _ ->
        Process.sleep(20)
        wait_epmd(tries - 1)
    end
  end

  defp net_kernel(name, names) do
    cond do
      node() == name ->
        :ok

      Node.alive?() ->
        {:error, "NEPTUNUS_NODE=#{name}, but the VM already runs distributed as #{node()}"}

      true ->
        case :net_kernel.start(name, %{name_domain: names}) do
          {:ok, _} ->
            :ok

          {:error, reason} ->
            {:error,
             "cannot start distribution as NEPTUNUS_NODE=#{name}: #{inspect(reason)} " <>
               "(is epmd running, is the name free, does the host name resolve?)"}
        end
    end
  end
end
