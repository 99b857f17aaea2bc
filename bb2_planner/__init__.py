"""bb2_planner"""
