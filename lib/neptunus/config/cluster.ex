defmodule Neptunus.Config.Cluster do
  @moduledoc """
  Distribution (a fleet of nodes, see `Neptunus.Fleet`): which node this is, which nodes it
  joins, and how the nodes talk.

  | variable              | meaning                                                 | default |
  |-----------------------|---------------------------------------------------------|---------|
  | `NEPTUNUS_NODE`       | the node's name, `name@host` (e.g. `rov1@10.0.0.2`)     | not distributed |
  | `NEPTUNUS_COOKIE`     | the cluster's shared secret, ≥ 32 printable characters  | required with `NEPTUNUS_NODE` |
  | `NEPTUNUS_CLUSTER`    | comma-separated node names to connect to                | none |
  | `NEPTUNUS_DIST_CERT`  | PEM certificate for TLS distribution                    | none |
  | `NEPTUNUS_DIST_KEY`   | its PEM private key                                     | none |
  | `NEPTUNUS_DIST_CACERT`| PEM CA that signs every node's certificate              | none |

  A node whose host is not loopback (`127.0.0.0/8`, `::1`, `localhost`) runs distribution
  over TLS (`inet_tls_dist`, both ends verified against the CA): without the three
  `NEPTUNUS_DIST_*` files it refuses to start, saying what to set, as the web refuses to
  serve beyond loopback without a secret. The VM must be started with
  `-proto_dist inet_tls -ssl_dist_optfile FILE` (the options are fixed when the VM starts;
  `ssl_dist_optfile/1` writes the file's content), which `check_proto_dist/2` verifies at
  boot. A loopback node listens for distribution on loopback only.

  The cookie is root on every node of the cluster (whoever has it runs any code there): it
  is never logged, and no error message shows it.

  Pure: parses the environment map, reads nothing else but whether the named files exist.
  """

  alias Neptunus.Config

  @min_cookie 32

  @typedoc "TLS distribution files (absolute paths)."
  @type tls :: %{certfile: String.t(), keyfile: String.t(), cacertfile: String.t()}

  @typedoc """
  A distributed node: its name, `:longnames` (host with a dot or an IP) or `:shortnames`,
  the cookie, the other nodes to connect to, whether its host is loopback, and TLS (nil:
  plain TCP, loopback only).
  """
  @type t :: %{
          node: node(),
          names: :longnames | :shortnames,
          cookie: atom(),
          cluster: [node()],
          loopback: boolean(),
          tls: tls() | nil
        }

  @doc """
  The node's distribution settings, or nil when `NEPTUNUS_NODE` is unset (a single node,
  as without a fleet).

      iex> Neptunus.Config.Cluster.cluster!(%{})
      nil
      iex> c = Neptunus.Config.Cluster.cluster!(%{"NEPTUNUS_NODE" => "rov1@127.0.0.1",
      ...>   "NEPTUNUS_COOKIE" => String.duplicate("k", 32), "NEPTUNUS_CLUSTER" => "top@127.0.0.1"})
      iex> Map.take(c, [:node, :names, :cluster, :loopback, :tls])
      %{node: :"rov1@127.0.0.1", names: :longnames, cluster: [:"top@127.0.0.1"], loopback: true, tls: nil}
  """
  @spec cluster!(Config.env()) :: t() | nil
  def cluster!(env) do
    case blank(env, "NEPTUNUS_NODE") do
      nil ->
        for variable <- ["NEPTUNUS_COOKIE", "NEPTUNUS_CLUSTER"] ++ dist_variables(),
            blank(env, variable) != nil do
          raise ArgumentError,
                "#{variable} is set but NEPTUNUS_NODE is not: set NEPTUNUS_NODE (e.g. " <>
                  "rov1@127.0.0.1) to run distributed, or unset #{variable}"
        end

        nil

      name ->
        {node, host} = node_name!("NEPTUNUS_NODE", name)
        loopback = loopback?(host)

        %{
          node: node,
          names: names(host),
          cookie: cookie!(blank(env, "NEPTUNUS_COOKIE")),
          cluster: cluster_nodes!(blank(env, "NEPTUNUS_CLUSTER"), node),
          loopback: loopback,
          tls: tls!(env, loopback, name)
        }
    end
  end

  defp dist_variables, do: ["NEPTUNUS_DIST_CERT", "NEPTUNUS_DIST_KEY", "NEPTUNUS_DIST_CACERT"]

  defp blank(env, variable) do
    case env |> Map.get(variable, "") |> String.trim() do
      "" -> nil
      value -> value
    end
  end

  defp node_name!(variable, value) do
    case String.split(value, "@") do
      [name, host] ->
        if name =~ ~r/\A[A-Za-z0-9_-]+\z/ and host =~ ~r/\A[A-Za-z0-9_.:-]+\z/,
          do: {String.to_atom(value), host},
          else: bad_name!(variable, value)

      _ ->
        bad_name!(variable, value)
    end
  end

  @spec bad_name!(String.t(), String.t()) :: no_return()
  defp bad_name!(variable, value),
    do: Config.bad!(variable, value, "a node name name@host, e.g. rov1@10.0.0.2 or top@localhost")

  defp names(host) do
    if String.contains?(host, ".") or String.contains?(host, ":"),
      do: :longnames,
      else: :shortnames
  end

  @doc """
  Whether a node's `host` is loopback (pure: a name other than `localhost` is not).

      iex> Enum.map(["127.0.0.1", "127.1.2.3", "::1", "localhost", "10.0.0.2", "rov1"], &Neptunus.Config.Cluster.loopback?/1)
      [true, true, true, true, false, false]
  """
  @spec loopback?(String.t()) :: boolean()
  def loopback?("localhost"), do: true

  def loopback?(host) do
    case :inet.parse_address(String.to_charlist(host)) do
      {:ok, {127, _, _, _}} -> true
      {:ok, {0, 0, 0, 0, 0, 0, 0, 1}} -> true
      _ -> false
    end
  end

  # The cookie's value never appears in a message.
  defp cookie!(nil) do
    raise ArgumentError,
          "NEPTUNUS_COOKIE is not set: a distributed node (NEPTUNUS_NODE) needs the cluster's " <>
            "cookie, at least #{@min_cookie} printable characters, the same on every node " <>
            "(e.g. from `openssl rand -base64 33`)"
  end

  defp cookie!(cookie) do
    cond do
      String.length(cookie) < @min_cookie ->
        raise ArgumentError,
              "NEPTUNUS_COOKIE is too short: expected at least #{@min_cookie} characters " <>
                "(e.g. from `openssl rand -base64 33`)"

      not (cookie =~ ~r/\A[\x21-\x7e]+\z/) ->
        raise ArgumentError,
              "NEPTUNUS_COOKIE is not valid: expected printable ASCII characters without spaces"

      true ->
        String.to_atom(cookie)
    end
  end

  defp cluster_nodes!(nil, _self), do: []

  defp cluster_nodes!(spec, self) do
    spec
    |> String.split(",")
    |> Enum.map(&String.trim/1)
    |> Enum.map(fn
      "" ->
        Config.bad!(
          "NEPTUNUS_CLUSTER",
          spec,
          "comma-separated node names, e.g. rov1@10.0.0.2,top@10.0.0.1"
        )

      name ->
        name |> then(&node_name!("NEPTUNUS_CLUSTER", &1)) |> elem(0)
    end)
    |> Enum.reject(&(&1 == self))
    |> Enum.uniq()
  end

  defp tls!(env, loopback, name) do
    case Enum.map(dist_variables(), &{&1, blank(env, &1)}) do
      [{_, nil}, {_, nil}, {_, nil}] when loopback ->
        nil

      [{_, nil}, {_, nil}, {_, nil}] ->
        raise ArgumentError,
              "NEPTUNUS_NODE=#{name} is not on loopback: distribution beyond loopback runs " <>
                "over TLS; set NEPTUNUS_DIST_CERT, NEPTUNUS_DIST_KEY and NEPTUNUS_DIST_CACERT " <>
                "(PEM files), or name the node on loopback (e.g. #{hd(String.split(name, "@"))}@127.0.0.1)"

      files ->
        for {variable, nil} <- files do
          Config.bad!(
            variable,
            "",
            "a PEM file: TLS distribution needs all of " <> Enum.join(dist_variables(), ", ")
          )
        end

        for {variable, path} <- files,
            not File.regular?(path),
            do: Config.bad!(variable, path, "a readable PEM file (no such file)")

        [cert, key, ca] = Enum.map(files, fn {_, path} -> Path.expand(path) end)
        %{certfile: cert, keyfile: key, cacertfile: ca}
    end
  end

  @doc """
  The content of the `-ssl_dist_optfile` for `tls` (an Erlang term): both ends present
  their certificate and verify the other's against the CA.
  """
  @spec ssl_dist_optfile(tls()) :: String.t()
  def ssl_dist_optfile(%{certfile: cert, keyfile: key, cacertfile: ca}) do
    side =
      [certfile: String.to_charlist(cert), keyfile: String.to_charlist(key)] ++
        [cacertfile: String.to_charlist(ca), verify: :verify_peer]

    term = [server: side ++ [fail_if_no_peer_cert: true], client: side]
    :io_lib.format(~c"~p.~n", [term]) |> IO.iodata_to_binary()
  end

  @doc """
  Whether the VM runs the distribution `cluster` asks for: `proto_dist` is what the VM was
  started with (`:init.get_argument(:proto_dist)`). TLS needs `-proto_dist inet_tls`; the
  error says what to set.

      iex> Neptunus.Config.Cluster.check_proto_dist(%{tls: nil}, :error)
      :ok
  """
  @spec check_proto_dist(
          %{required(:tls) => tls() | nil, optional(atom()) => term()},
          {:ok, [[charlist()]]} | :error
        ) ::
          :ok | {:error, String.t()}
  def check_proto_dist(%{tls: nil}, _proto_dist), do: :ok
  def check_proto_dist(%{tls: _}, {:ok, [[~c"inet_tls"]]}), do: :ok

  def check_proto_dist(%{tls: _}, _proto_dist) do
    {:error,
     "TLS distribution (NEPTUNUS_DIST_*) needs the VM started with " <>
       "ELIXIR_ERL_OPTIONS=\"-proto_dist inet_tls -ssl_dist_optfile FILE\" " <>
       "(FILE: Neptunus.Config.Cluster.ssl_dist_optfile/1, see README \"A fleet\")"}
  end
end
