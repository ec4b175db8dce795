defmodule Neptunus.Protocol.UnderwaterGPS do
  @moduledoc """
  The Water Linked Underwater GPS HTTP API (`/api/v1`), the parts a vehicle needs: the
  locator's acoustic position and the vehicle's depth sent to the topside. Pure: decode and
  encode the JSON bodies; `Neptunus.Position.UGPS` makes the requests (OTP's `:httpc`) and
  `Neptunus.Sim.UGPSServer` answers them on loopback with the same bodies.

    * `GET /api/v1/position/acoustic/filtered` → the locator's position relative to the
      topside ("master electronics"): `x`, `y` (m), `z` (m, depth), `std` (m, the position's
      accuracy), `position_valid`, and per receiver `receiver_distance`, `receiver_rssi`,
      `receiver_nsd`, `receiver_valid`. The fix carries no time: the reader knows only when it
      read it (see `Neptunus.Position.UGPS` for how its age is accounted for).
    * `PUT /api/v1/external/depth` with `{"depth": m, "temp": °C}` (depth 0..500 m,
      temperature −10..60 °C): the locator's depth from the vehicle's own depth sensor. A
      Locator-A1 system (the locator on a ROV's tether) needs it to give a position at all.

  `x` and `y` are in the topside's frame; which way its `x` points is the topside's
  orientation (its compass, or a static orientation in its configuration). The driver turns
  them into north and east with the rotation it is configured with.
  """

  alias Neptunus.JSON
  alias Neptunus.Validate, as: V

  @acoustic_path "/api/v1/position/acoustic/filtered"
  @depth_path "/api/v1/external/depth"

  @typedoc "An acoustic fix (m)."
  @type fix :: %{
          x: float(),
          y: float(),
          z: float(),
          std: float(),
          valid: boolean(),
          receivers: [map()]
        }

  @doc "The acoustic position's path."
  @spec acoustic_path() :: String.t()
  def acoustic_path, do: @acoustic_path

  @doc "The external depth's path."
  @spec depth_path() :: String.t()
  def depth_path, do: @depth_path

  @doc """
  Decodes the body of `GET /api/v1/position/acoustic/filtered`.

      iex> Neptunus.Protocol.UnderwaterGPS.decode_fix(
      ...>   ~s({"x":3.5,"y":-1.0,"z":4.2,"std":0.4,"position_valid":true,) <>
      ...>   ~s("receiver_distance":[],"receiver_rssi":[],"receiver_nsd":[],"receiver_valid":[]}))
      {:ok, %{x: 3.5, y: -1.0, z: 4.2, std: 0.4, valid: true, receivers: []}}

      iex> Neptunus.Protocol.UnderwaterGPS.decode_fix(~s({"x":3.5}))
      {:error, "acoustic position: missing field: y"}
  """
  @spec decode_fix(binary()) :: {:ok, fix()} | {:error, String.t()}
  def decode_fix(body) when is_binary(body) do
    with {:ok, map} <- JSON.decode(body),
         :ok <- object(map),
         {:ok, x} <- field(map, "x", &V.number/2),
         {:ok, y} <- field(map, "y", &V.number/2),
         {:ok, z} <- field(map, "z", &V.number/2),
         {:ok, std} <- field(map, "std", &V.number(&1, &2, min: 0)),
         {:ok, valid} <- field(map, "position_valid", &V.boolean/2),
         {:ok, receivers} <- receivers(map) do
      {:ok,
       %{x: x * 1.0, y: y * 1.0, z: z * 1.0, std: std * 1.0, valid: valid, receivers: receivers}}
    else
      {:error, reason} -> {:error, "acoustic position: " <> reason}
    end
  end

  def decode_fix(_body), do: {:error, "acoustic position: the body must be text"}

  defp object(map) when is_map(map), do: :ok
  defp object(other), do: {:error, "must be a JSON object, got #{V.show(other)}"}

  defp field(map, key, check) do
    case Map.fetch(map, key) do
      {:ok, value} -> check.(value, key)
      :error -> {:error, "missing field: #{key}"}
    end
  end

  # the receivers' lists (optional here: older firmware sends fewer), zipped by index
  defp receivers(map) do
    lists =
      for key <- ~w(receiver_distance receiver_rssi receiver_nsd receiver_valid),
          do: {key, Map.get(map, key, [])}

    case Enum.find(lists, fn {_k, v} -> not is_list(v) end) do
      {key, value} ->
        {:error, "#{key} must be a list, got #{V.show(value)}"}

      nil ->
        [d, r, n, v] = Enum.map(lists, &elem(&1, 1))
        count = lists |> Enum.map(&length(elem(&1, 1))) |> Enum.max()

        {:ok,
         for i <- 0..(count - 1)//1 do
           %{
             distance: Enum.at(d, i),
             rssi: Enum.at(r, i),
             nsd: Enum.at(n, i),
             valid: Enum.at(v, i)
           }
         end}
    end
  end

  @doc "The body of an acoustic position (the simulated topside's side)."
  @spec encode_fix(fix()) :: binary()
  def encode_fix(fix) do
    JSON.encode!(%{
      x: fix.x,
      y: fix.y,
      z: fix.z,
      std: fix.std,
      position_valid: fix.valid,
      receiver_distance: Enum.map(fix.receivers, & &1.distance),
      receiver_rssi: Enum.map(fix.receivers, & &1.rssi),
      receiver_nsd: Enum.map(fix.receivers, & &1.nsd),
      receiver_valid: Enum.map(fix.receivers, & &1.valid)
    })
  end

  @doc """
  The body of `PUT /api/v1/external/depth`: depth clamped to the API's 0..500 m (a vehicle at
  the surface may read a few centimetres above it), temperature to −10..60 °C.

      iex> Neptunus.JSON.decode(Neptunus.Protocol.UnderwaterGPS.encode_depth(-0.02, 11.5))
      {:ok, %{"depth" => 0.0, "temp" => 11.5}}
  """
  @spec encode_depth(number(), number()) :: binary()
  def encode_depth(depth, temp) when is_number(depth) and is_number(temp) do
    JSON.encode!(%{depth: clamp(depth, 0.0, 500.0), temp: clamp(temp, -10.0, 60.0)})
  end

  defp clamp(x, lo, hi), do: x |> max(lo) |> min(hi) |> Kernel.*(1.0)

  @doc """
  Decodes the body of `PUT /api/v1/external/depth` (the simulated topside's side) as the API
  specifies it: `depth` in 0..500 m and `temp` in −10..60 °C, both required.

      iex> Neptunus.Protocol.UnderwaterGPS.decode_depth(~s({"depth": 3.2, "temp": 11}))
      {:ok, 3.2, 11.0}

      iex> Neptunus.Protocol.UnderwaterGPS.decode_depth(~s({"depth": 3.2}))
      {:error, "missing field: temp"}
  """
  @spec decode_depth(binary()) :: {:ok, float(), float()} | {:error, String.t()}
  def decode_depth(body) when is_binary(body) do
    with {:ok, map} <- JSON.decode(body),
         :ok <- V.object(map, "", ["depth", "temp"]),
         {:ok, depth} <- V.required(map, "", "depth", &V.number(&1, &2, min: 0, max: 500)),
         {:ok, temp} <- V.required(map, "", "temp", &V.number(&1, &2, min: -10, max: 60)) do
      {:ok, depth * 1.0, temp * 1.0}
    end
  end

  @doc """
  The body the API answers an operation (`PUT`) with: `{"success": true}`, or
  `{"success": false, "error": reason}`.
  """
  @spec encode_operation(:ok | {:error, String.t()}) :: binary()
  def encode_operation(:ok), do: JSON.encode!(%{success: true})
  def encode_operation({:error, reason}), do: JSON.encode!(%{success: false, error: reason})

  @doc """
  Decodes an operation's answer: `:ok`, or `{:error, reason}` (the API's `error`, or why the
  body is not one).

      iex> Neptunus.Protocol.UnderwaterGPS.decode_operation(~s({"success": false, "error": "no locator"}))
      {:error, "no locator"}
  """
  @spec decode_operation(binary()) :: :ok | {:error, String.t()}
  def decode_operation(body) when is_binary(body) do
    case JSON.decode(body) do
      {:ok, %{"success" => true}} -> :ok
      {:ok, %{"success" => false, "error" => error}} when is_binary(error) -> {:error, error}
      {:ok, %{"success" => false}} -> {:error, "the topside refused it (no reason given)"}
      {:ok, other} -> {:error, "not an operation response: #{V.show(other)}"}
      {:error, reason} -> {:error, reason}
    end
  end
end
