"""Serial/MAVLink link layer and the emulated micro-manipulator."""
