"""bb2_control"""
