"""The files the science reads and writes: YAML with its schema, CSV tables, Parquet."""
