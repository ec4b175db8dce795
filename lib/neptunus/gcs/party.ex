defmodule Neptunus.GCS.Party do
  @moduledoc """
  A ground station as the helm sees it (`t:Neptunus.Vehicle.Helm.party/0`): one session of
  one ground station, told apart from browsers and from other sessions by its id,
  `gcs:<system id>:<session>` (`id/2`). The helm broadcasts the pilot's id, so anyone can
  tell which ground station holds a helm (`sysid/1`, CONTROL_STATUS' `sysid_in_control`).
  """

  @doc """
  The party id of ground station system `sysid` on session `session` (the endpoint and the
  peer, e.g. `udpin0/127.0.0.1:43210`).

      iex> Neptunus.GCS.Party.id(255, "udpin0/127.0.0.1:43210")
      "gcs:255:udpin0/127.0.0.1:43210"
  """
  @spec id(0..255, String.t()) :: String.t()
  def id(sysid, session), do: "gcs:#{sysid}:#{session}"

  @doc """
  The ground station's system id in a party id, or nil for a browser's.

      iex> Neptunus.GCS.Party.sysid("gcs:255:udpin0/127.0.0.1:43210")
      255
      iex> Neptunus.GCS.Party.sysid("c1f3e")
      nil
  """
  @spec sysid(term()) :: 0..255 | nil
  def sysid("gcs:" <> rest) do
    with [n, _session] <- String.split(rest, ":", parts: 2),
         {n, ""} when n in 0..255 <- Integer.parse(n) do
      n
    else
      _ -> nil
    end
  end

  def sysid(_id), do: nil
end
