"""bb2_sim"""
