defmodule Neptunus.Config.OS do
  @moduledoc """
  The operating system settings the node asks for (`config :neptunus, :os_time_slice_ns`,
  see `Neptunus.OS`): `NEPTUNUS_OS_SLICE_US`.
  """

  alias Neptunus.Config

  @doc """
  The scheduler time slice the node's threads ask the OS for (`Neptunus.OS`), in
  nanoseconds: `NEPTUNUS_OS_SLICE_US` in µs, 100..100000 (default 100), or `default` (nil:
  leave the kernel's own).

      iex> Neptunus.Config.OS.os_time_slice_ns!(%{})
      100000
      iex> Neptunus.Config.OS.os_time_slice_ns!(%{"NEPTUNUS_OS_SLICE_US" => "500"})
      500000
      iex> Neptunus.Config.OS.os_time_slice_ns!(%{"NEPTUNUS_OS_SLICE_US" => "default"})
      nil
  """
  @spec os_time_slice_ns!(Config.env()) :: pos_integer() | nil
  def os_time_slice_ns!(env) do
    case Config.integer_or_word!(
           env,
           "NEPTUNUS_OS_SLICE_US",
           "100",
           100..100_000,
           "default",
           "microseconds"
         ) do
      nil -> nil
      us -> us * 1000
    end
  end
end
