"""3D views of runs: a self-contained HTML page over meshcat's three.js viewer (html.py), the
scene's drawn geometry (geometry.py), and the live view of the emulated device
(live_server.py)."""
