"""stewart-sim, the application: command line, studies, run pipelines, reports and plots.

It imports the plant library (`stewart_fmu`), the control layer (`controller`) and the link and
device layer (`hil`); nothing imports it.
"""
