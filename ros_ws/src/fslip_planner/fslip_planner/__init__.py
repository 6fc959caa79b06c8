"""fslip_planner."""
