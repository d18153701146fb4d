"""Sensors: the sensor base and ray caster, lasers, contact/encoder/GPS/IMU, range cones, cameras."""
