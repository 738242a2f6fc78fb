"""snow"""
