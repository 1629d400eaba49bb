"""bpmcal.lab: the virtual rock laboratory (specimen genesis, UCS test, drop-hammer impact)."""
