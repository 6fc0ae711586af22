"""The closed-loop run: per-axis controllers around the plant in this process, an exported
FMU (run_files) or the emulated device over a link (over_link, link_figures)."""
