defmodule Neptunus.Config.Helm do
  @moduledoc """
  Helm timing (`config :neptunus, :helm`, see `Neptunus.Vehicle.Helm`):

  | variable                       | meaning                                             | default        |
  |--------------------------------|-----------------------------------------------------|----------------|
  | `NEPTUNUS_DEADMAN_MS`          | pilot silence that stops the vehicle (ms)           | 500            |
  | `NEPTUNUS_REQUEST_TIMEOUT_MS`  | how long a control request waits for the pilot (ms) | 10000          |
  | `NEPTUNUS_TAKEOVER_MS`         | main station takeover warning countdown (ms)        | 3000           |
  """

  alias Neptunus.Config

  @doc """
  Helm timing (`config :neptunus, :helm`, see `Neptunus.Vehicle.Helm`).

      iex> Neptunus.Config.Helm.helm!(%{})
      [deadman_ms: 500, request_timeout_ms: 10000, takeover_ms: 3000]
  """
  @spec helm!(Config.env()) :: keyword(pos_integer())
  def helm!(env) do
    default = Neptunus.Vehicle.Helm.defaults()

    [
      deadman_ms:
        Config.env_integer!(env, "NEPTUNUS_DEADMAN_MS", default[:deadman_ms], 100..10_000),
      request_timeout_ms:
        Config.env_integer!(
          env,
          "NEPTUNUS_REQUEST_TIMEOUT_MS",
          default[:request_timeout_ms],
          1000..120_000
        ),
      takeover_ms:
        Config.env_integer!(env, "NEPTUNUS_TAKEOVER_MS", default[:takeover_ms], 0..30_000)
    ]
  end
end
