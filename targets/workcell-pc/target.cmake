# The workcell PC: idi-workcell with the Biclops cameras (V4L2), the PTUs, Staubli controllers and
# Barrett hand on serial ports. The vehicle's CAN is not needed here.
set(IDI_BACKEND_V4L2 ON)
set(IDI_BACKEND_SERIAL ON)
set(IDI_BACKEND_SOCKETCAN OFF)
