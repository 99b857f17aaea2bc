"""bb2_msgs_py"""
