defmodule Neptunus.Protocol.WaterLinkedDVL do
  @moduledoc """
  The Water Linked DVL (A50, A125) TCP JSON protocol (`json_v3.x`): the DVL serves it on TCP
  port 16171, one JSON object per line (`\\n`). Pure: decode what the DVL sends, encode what
  we send it — and, for the simulated DVL (`Neptunus.Sim.DVLServer`), the other way round, so
  the simulator speaks the same bytes the real driver reads.

  ## What the DVL sends

    * **Velocity reports** (`"type": "velocity"`, 2–15 Hz by altitude): `vx`, `vy`, `vz` (m/s,
      in the DVL's frame — the vehicle's frame when its *mounting rotation offset* is set: x
      forward, y starboard, z down), `fom` (figure of merit: the velocities' accuracy, m/s),
      `covariance` (3×3, (m/s)²), `altitude` (m to the reflecting surface), `velocity_valid`
      (the DVL has bottom lock: altitude and velocities valid), `status` (bit 0: high
      temperature), `time` (ms since the previous report), `time_of_validity` and
      `time_of_transmission` (Unix µs, the DVL's clock: their difference is how old the
      measurement was when it was sent), `transducers` (per beam: `id`, `velocity`, `distance`,
      `rssi`, `nsd`, `beam_valid`) and, from `json_v3.2`, `tracking_mode` (`bottom` or
      `water`). A `velocity_water` report (water tracking) is velocity through the water, not
      over the ground: it decodes with `tracking: :water` and is never navigation's velocity.
    * **Dead-reckoning reports** (`"type": "position_local"`, 5 Hz): the DVL's own integrated
      position `x`, `y`, `z` (m, in the frame of its last dead-reckoning reset), `std` (m),
      `roll`, `pitch`, `yaw` (degrees on the wire; radians here), `ts` (s), `status`.
    * **Responses** (`"type": "response"`) to a command: `response_to`, `success`,
      `error_message`, `result`.

  Other report types decode as `{:other, type}` (a newer firmware's additions are not
  garbage).

  ## What we send

  Commands, one JSON object per line: `{"command": "reset_dead_reckoning"}`,
  `{"command": "calibrate_gyro"}` (the DVL should be still; it may take up to 15 s),
  `{"command": "get_config"}`, `{"command": "trigger_ping"}`.

  ## Bad input

  `decode/1` never raises. A line that is not JSON, not an object, lacks a field or has one of
  the wrong type is `{:error, reason}` naming the field, e.g.
  `velocity report: vx must be a number, got "fast"`.
  """

  alias Neptunus.{JSON, Validate}

  @format "json_v3.1"
  @commands ~w(reset_dead_reckoning calibrate_gyro get_config trigger_ping)
  @deg :math.pi() / 180

  @typedoc "A velocity report (SI units; see the moduledoc)."
  @type velocity :: %{
          vx: float(),
          vy: float(),
          vz: float(),
          fom: float(),
          covariance: [[float()]] | nil,
          altitude: float(),
          valid: boolean(),
          status: integer(),
          time_ms: float() | nil,
          time_of_validity_us: integer() | nil,
          time_of_transmission_us: integer() | nil,
          tracking: :bottom | :water,
          transducers: [map()]
        }

  @typedoc "A dead-reckoning report (m, rad)."
  @type position_local :: %{
          ts: float(),
          x: float(),
          y: float(),
          z: float(),
          std: float(),
          roll: float(),
          pitch: float(),
          yaw: float(),
          status: integer()
        }

  @typedoc "A response to a command."
  @type response :: %{
          to: String.t(),
          success: boolean(),
          error_message: String.t(),
          result: term()
        }

  @type report ::
          {:velocity, velocity()}
          | {:position_local, position_local()}
          | {:response, response()}
          | {:other, String.t()}

  @type command :: :reset_dead_reckoning | :calibrate_gyro | :get_config | :trigger_ping

  @doc "The TCP port the DVL serves its JSON protocol on."
  @spec port() :: 16_171
  def port, do: 16_171

  @doc "The commands `encode_command/1` knows."
  @spec commands() :: [command()]
  def commands, do: Enum.map(@commands, &String.to_atom/1)

  # --- decoding (what the DVL sends) ----------------------------------------------------

  @doc """
  Decodes one line from the DVL.

      iex> {:ok, {:velocity, v}} = Neptunus.Protocol.WaterLinkedDVL.decode(
      ...>   ~s({"type":"velocity","vx":0.1,"vy":0,"vz":0,"fom":0.002,"altitude":3.5,) <>
      ...>   ~s("velocity_valid":true,"status":0}))
      iex> {v.vx, v.valid, v.altitude, v.tracking}
      {0.1, true, 3.5, :bottom}

      iex> Neptunus.Protocol.WaterLinkedDVL.decode(~s({"type":"velocity","vx":"fast"}))
      {:error, "velocity report: vx must be a number, got \\"fast\\""}
  """
  @spec decode(binary()) :: {:ok, report()} | {:error, String.t()}
  def decode(line) when is_binary(line) do
    case JSON.decode(line) do
      {:ok, %{"type" => type} = map} when is_binary(type) -> report(type, map)
      {:ok, %{} = map} -> if Map.has_key?(map, "type"), do: bad_type(map), else: no_type()
      {:ok, other} -> {:error, "a report must be a JSON object, got #{show(other)}"}
      {:error, reason} -> {:error, reason}
    end
  end

  def decode(_line), do: {:error, "a report must be text"}

  defp bad_type(map), do: {:error, "type must be a string, got #{show(map["type"])}"}
  defp no_type, do: {:error, "a report needs a type"}

  defp report(type, map) when type in ["velocity", "velocity_water"] do
    tracking =
      case {type, map["tracking_mode"]} do
        {"velocity_water", _} -> :water
        {_, "water"} -> :water
        _ -> :bottom
      end

    with {:ok, vx} <- num(map, "vx"),
         {:ok, vy} <- num(map, "vy"),
         {:ok, vz} <- num(map, "vz"),
         {:ok, fom} <- num(map, "fom", min: 0),
         {:ok, altitude} <- num(map, "altitude"),
         {:ok, valid} <- bool(map, "velocity_valid"),
         {:ok, status} <- opt(map, "status", 0, &int/2),
         {:ok, time} <- opt(map, "time", nil, &number/2),
         {:ok, tov} <- opt(map, "time_of_validity", nil, &int/2),
         {:ok, tot} <- opt(map, "time_of_transmission", nil, &int/2),
         {:ok, cov} <- opt(map, "covariance", nil, &covariance/2),
         {:ok, transducers} <- opt(map, "transducers", [], &transducers/2) do
      {:ok,
       {:velocity,
        %{
          vx: vx,
          vy: vy,
          vz: vz,
          fom: fom,
          covariance: cov,
          altitude: altitude,
          valid: valid,
          status: status,
          time_ms: time,
          time_of_validity_us: tov,
          time_of_transmission_us: tot,
          tracking: tracking,
          transducers: transducers
        }}}
    end
    |> in_report("velocity report")
  end

  defp report("position_local", map) do
    with {:ok, ts} <- num(map, "ts"),
         {:ok, x} <- num(map, "x"),
         {:ok, y} <- num(map, "y"),
         {:ok, z} <- num(map, "z"),
         {:ok, std} <- num(map, "std", min: 0),
         {:ok, roll} <- num(map, "roll"),
         {:ok, pitch} <- num(map, "pitch"),
         {:ok, yaw} <- num(map, "yaw"),
         {:ok, status} <- opt(map, "status", 0, &int/2) do
      {:ok,
       {:position_local,
        %{
          ts: ts,
          x: x,
          y: y,
          z: z,
          std: std,
          roll: roll * @deg,
          pitch: pitch * @deg,
          yaw: yaw * @deg,
          status: status
        }}}
    end
    |> in_report("dead-reckoning report")
  end

  defp report("response", map) do
    with {:ok, to} <- field(map, "response_to", &string/2),
         {:ok, success} <- bool(map, "success"),
         {:ok, message} <- opt(map, "error_message", "", &string/2) do
      {:ok,
       {:response,
        %{to: to, success: success, error_message: message, result: Map.get(map, "result")}}}
    end
    |> in_report("response")
  end

  defp report(type, _map), do: {:ok, {:other, type}}

  defp in_report({:error, reason}, what), do: {:error, "#{what}: #{reason}"}
  defp in_report(ok, _what), do: ok

  defp covariance(rows, path) when is_list(rows) and length(rows) == 3 do
    Validate.map_ok(rows, fn
      [a, b, c], _i when is_number(a) and is_number(b) and is_number(c) ->
        {:ok, [a * 1.0, b * 1.0, c * 1.0]}

      row, i ->
        {:error, "#{path}[#{i}] must be a list of 3 numbers, got #{show(row)}"}
    end)
  end

  defp covariance(value, path), do: {:error, "#{path} must be a 3x3 matrix, got #{show(value)}"}

  defp transducers(list, path) when is_list(list) do
    Validate.map_ok(list, fn beam, i ->
      bpath = "#{path}[#{i}]"

      with true <- is_map(beam) || {:error, "#{bpath} must be an object, got #{show(beam)}"},
           {:ok, id} <- field(beam, "id", &int/2, bpath),
           {:ok, velocity} <- field(beam, "velocity", &number/2, bpath),
           {:ok, distance} <- field(beam, "distance", &number/2, bpath),
           {:ok, rssi} <- field(beam, "rssi", &number/2, bpath),
           {:ok, nsd} <- field(beam, "nsd", &number/2, bpath),
           {:ok, valid} <- field(beam, "beam_valid", &boolean/2, bpath) do
        {:ok,
         %{
           id: id,
           velocity: velocity,
           distance: distance,
           rssi: rssi,
           nsd: nsd,
           beam_valid: valid
         }}
      end
    end)
  end

  defp transducers(value, path), do: {:error, "#{path} must be a list, got #{show(value)}"}

  # --- field helpers ---

  defp num(map, key, opts \\ []) do
    with {:ok, x} <- field(map, key, &number/2) do
      case Keyword.fetch(opts, :min) do
        {:ok, min} when x < min ->
          {:error, "#{key} must be a number >= #{min}, got #{show(Map.get(map, key))}"}

        _ ->
          {:ok, x}
      end
    end
  end

  defp bool(map, key), do: field(map, key, &boolean/2)

  defp field(map, key, check, path \\ "") do
    name = if path == "", do: key, else: path <> "." <> key

    case Map.fetch(map, key) do
      {:ok, value} -> check.(value, name)
      :error -> {:error, "missing field: #{name}"}
    end
  end

  defp opt(map, key, default, check) do
    case Map.fetch(map, key) do
      {:ok, nil} -> {:ok, default}
      {:ok, value} -> check.(value, key)
      :error -> {:ok, default}
    end
  end

  defp number(x, _path) when is_number(x), do: {:ok, x * 1.0}
  defp number(x, path), do: {:error, "#{path} must be a number, got #{show(x)}"}

  defp int(x, _path) when is_integer(x), do: {:ok, x}
  defp int(x, _path) when is_float(x) and x == trunc(x) * 1.0, do: {:ok, trunc(x)}
  defp int(x, path), do: {:error, "#{path} must be an integer, got #{show(x)}"}

  defp boolean(x, _path) when is_boolean(x), do: {:ok, x}
  defp boolean(x, path), do: {:error, "#{path} must be true or false, got #{show(x)}"}

  defp string(x, _path) when is_binary(x), do: {:ok, x}
  defp string(x, path), do: {:error, "#{path} must be a string, got #{show(x)}"}

  defp show(value), do: Validate.show(value)

  # --- commands (what we send) --------------------------------------------------------------

  @doc """
  A command as the line to send.

      iex> Neptunus.Protocol.WaterLinkedDVL.encode_command(:reset_dead_reckoning)
      ~s({"command":"reset_dead_reckoning"}\\n)
  """
  @spec encode_command(command()) :: binary()
  def encode_command(command) when is_atom(command) do
    name = Atom.to_string(command)
    if name not in @commands, do: raise(ArgumentError, "unknown DVL command #{inspect(command)}")
    JSON.encode!(%{command: name}) <> "\n"
  end

  @doc """
  Decodes a command line (the simulated DVL's side): `{:ok, name}` for a command the DVL
  knows, `{:ok, {:unknown, name}}` for another, `{:error, reason}` for anything else.
  """
  @spec decode_command(binary()) ::
          {:ok, String.t() | {:unknown, String.t()}} | {:error, String.t()}
  def decode_command(line) do
    case JSON.decode(line) do
      {:ok, %{"command" => name}} when name in @commands -> {:ok, name}
      {:ok, %{"command" => name}} when is_binary(name) -> {:ok, {:unknown, name}}
      {:ok, _} -> {:error, "a command must be an object with a string \"command\""}
      {:error, reason} -> {:error, reason}
    end
  end

  # --- encoding reports (the simulated DVL's side) -----------------------------------------

  @doc "A velocity report as the DVL sends it (a line)."
  @spec encode_velocity(velocity()) :: binary()
  def encode_velocity(v) do
    %{
      time: v.time_ms,
      vx: v.vx,
      vy: v.vy,
      vz: v.vz,
      fom: v.fom,
      covariance: v.covariance,
      altitude: v.altitude,
      transducers:
        Enum.map(v.transducers, fn b ->
          %{
            id: b.id,
            velocity: b.velocity,
            distance: b.distance,
            rssi: b.rssi,
            nsd: b.nsd,
            beam_valid: b.beam_valid
          }
        end),
      velocity_valid: v.valid,
      status: v.status,
      tracking_mode: Atom.to_string(v.tracking),
      format: @format,
      type: if(v.tracking == :water, do: "velocity_water", else: "velocity"),
      time_of_validity: v.time_of_validity_us,
      time_of_transmission: v.time_of_transmission_us
    }
    |> line()
  end

  @doc "A dead-reckoning report as the DVL sends it (angles in degrees on the wire)."
  @spec encode_position_local(position_local()) :: binary()
  def encode_position_local(p) do
    %{
      ts: p.ts,
      x: p.x,
      y: p.y,
      z: p.z,
      std: p.std,
      roll: p.roll / @deg,
      pitch: p.pitch / @deg,
      yaw: p.yaw / @deg,
      type: "position_local",
      status: p.status,
      format: @format
    }
    |> line()
  end

  @doc "A response to a command as the DVL sends it."
  @spec encode_response(String.t(), boolean(), String.t(), term()) :: binary()
  def encode_response(to, success, error_message \\ "", result \\ nil) do
    %{
      response_to: to,
      success: success,
      error_message: error_message,
      result: result,
      format: @format,
      type: "response"
    }
    |> line()
  end

  defp line(map), do: JSON.encode!(map) <> "\n"
end
