"""Planning a campaign and simulating one."""
