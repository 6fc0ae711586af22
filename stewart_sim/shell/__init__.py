"""The command line's shell: argument types, what reaches the terminal, Ctrl-C, result
sets written all or nothing, progress, how long a run may be, and the pieces every report
shares (Markdown escaping, PNG figures)."""
