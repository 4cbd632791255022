"""The `stiffcomp` command line: thin wrappers over the stiffness, service and plc_interface packages."""
