"""What the service's two processes and every listener stand on, knowing no protocol: absolute deadlines and
real-time scheduling, the log format, listeners and why one cannot listen, TLS and certificates, the client
table, rate-limited logs, recovery after faults, the shared settings and the root of the I/O side's exceptions."""
