"""bpmcal.plots: functions that take tables/results and return matplotlib Figures."""
