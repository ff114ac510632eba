# The amd64 laptop on the Segway RMP: idi-rmp with two V4L2 (USB) cameras and the RMP's CAN interface
# (a USB-CAN adapter seen as SocketCAN can0); serial for a USB-serial CAN adapter (slcan) if used.
set(IDI_BACKEND_V4L2 ON)
set(IDI_BACKEND_SERIAL ON)
set(IDI_BACKEND_SOCKETCAN ON)
