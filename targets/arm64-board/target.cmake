# An arm64 single-board computer on the vehicle (cross-compiled: presets cross-arm64-rmp and
# cross-arm64). Runs idi-rmp: two V4L2 cameras and the RMP on SocketCAN; no serial devices.
# idi-workcell is built only by the cross-arm64 preset, whose sysroot has Ceres.
set(IDI_BACKEND_V4L2 ON)
set(IDI_BACKEND_SERIAL OFF)
set(IDI_BACKEND_SOCKETCAN ON)
