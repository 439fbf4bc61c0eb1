"""Scenarios: synthetic worlds and cameras, closed-loop simulation and fault injection around the
same control loop a robot runs. Time here is always simulated.
"""
