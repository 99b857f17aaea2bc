"""bb2_tools"""
