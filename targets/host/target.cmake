# A developer desktop or CI machine: every binary, the simulated and replay backends, and the
# Linux hardware backends (V4L2, serial, SocketCAN) so they are compiled and tested everywhere.
set(IDI_BACKEND_V4L2 ON)
set(IDI_BACKEND_SERIAL ON)
set(IDI_BACKEND_SOCKETCAN ON)
