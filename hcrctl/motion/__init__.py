"""The motion governor: every source that asks for continuous motion offers it here, and one component
writes it, holds the lease (the deadman) on its own clock and sends the stops."""
