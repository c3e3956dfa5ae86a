"""Small private helpers shared across handeye's modules (atomic writes, digests, progress,
lazy imports). Nothing here is public API."""
