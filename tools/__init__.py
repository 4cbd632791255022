"""The `stiffcomp` command line: thin wrappers over the science, the service, the I/O process and the cell's programs."""
