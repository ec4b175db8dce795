defmodule Neptunus.Config.Recording do
  @moduledoc """
  Recording (`config :neptunus, :recording`, see `Neptunus.Vehicle.Recorder`):
  `NEPTUNUS_RECORDINGS`, `NEPTUNUS_RECORDING_MAX_MB`, `NEPTUNUS_RECORDING_MIN_FREE_MB`,
  `NEPTUNUS_RECORDING_KEEP_DAYS`, `NEPTUNUS_DIVE_GAP_MIN` (see `recording!/2`).
  """

  alias Neptunus.Config

  @mib 1024 * 1024

  @doc """
  Recording (`config :neptunus, :recording`, see `Neptunus.Vehicle.Recorder`):
  `NEPTUNUS_RECORDINGS` — the directory (relative to the working directory, created when
  needed) or `off`; `NEPTUNUS_RECORDING_MIN_FREE_MB` — recording stops while less disk is
  free (default 512); `NEPTUNUS_RECORDING_MAX_MB` — size of one entries file of a dive before
  the next is started (1..65536, default 256); `NEPTUNUS_RECORDING_KEEP_DAYS` — each
  vehicle's recorder deletes its dives last written more than this many days ago (1..3650),
  or `forever` (the default: nothing is deleted by the server); `NEPTUNUS_DIVE_GAP_MIN` — a
  pilot taking the helm after it was free this many minutes begins a new dive (0..1440,
  default 10; 0: a dive lasts as long as the recorder runs).

      iex> Neptunus.Config.Recording.recording!(%{}, "recordings")
      %{dir: "recordings", max_bytes: 268435456, min_free_bytes: 536870912, keep_ms: nil, gap_ms: 600000}
      iex> Neptunus.Config.Recording.recording!(%{"NEPTUNUS_DIVE_GAP_MIN" => "0"}, "recordings").gap_ms
      nil
      iex> Neptunus.Config.Recording.recording!(%{"NEPTUNUS_RECORDING_KEEP_DAYS" => "30"}, "recordings").keep_ms
      2592000000
      iex> Neptunus.Config.Recording.recording!(%{"NEPTUNUS_RECORDINGS" => "off"}, "recordings").dir
      nil
  """
  @spec recording!(Config.env(), Path.t() | nil) :: %{
          dir: Path.t() | nil,
          max_bytes: pos_integer(),
          min_free_bytes: non_neg_integer(),
          keep_ms: pos_integer() | nil,
          gap_ms: pos_integer() | nil
        }
  def recording!(env, default_dir) do
    dir =
      case env |> Map.get("NEPTUNUS_RECORDINGS", default_dir || "off") |> String.trim() do
        "off" -> nil
        "" -> Config.bad!("NEPTUNUS_RECORDINGS", "", "a directory, or off")
        dir -> recording_dir!(dir)
      end

    defaults = Neptunus.Vehicle.Recorder.defaults()

    %{
      dir: dir,
      max_bytes:
        Config.env_integer!(env, "NEPTUNUS_RECORDING_MAX_MB", mib(defaults.max_bytes), 1..65_536) *
          @mib,
      min_free_bytes:
        Config.env_integer!(
          env,
          "NEPTUNUS_RECORDING_MIN_FREE_MB",
          mib(defaults.min_free_bytes),
          0..1_048_576
        ) * @mib,
      keep_ms: keep_ms!(env),
      gap_ms:
        case Config.env_integer!(
               env,
               "NEPTUNUS_DIVE_GAP_MIN",
               div(defaults.gap_ms, 60_000),
               0..1440
             ) do
          0 -> nil
          minutes -> minutes * 60_000
        end
    }
  end

  defp keep_ms!(env) do
    case Config.integer_or_word!(
           env,
           "NEPTUNUS_RECORDING_KEEP_DAYS",
           "forever",
           1..3650,
           "forever",
           "a number of days"
         ) do
      nil -> nil
      days -> days * 86_400_000
    end
  end

  defp recording_dir!(dir) do
    case File.stat(dir) do
      {:ok, %File.Stat{type: :directory}} ->
        dir

      {:ok, _} ->
        Config.bad!("NEPTUNUS_RECORDINGS", dir, "a directory (this is a file), or off")

      {:error, :enoent} ->
        dir

      {:error, reason} ->
        Config.bad!("NEPTUNUS_RECORDINGS", dir, "a usable directory (#{reason}), or off")
    end
  end

  defp mib(bytes), do: div(bytes, @mib)
end
