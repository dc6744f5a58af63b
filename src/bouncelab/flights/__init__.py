"""flights"""
