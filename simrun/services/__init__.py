"""Services bound to robots: the drive service and the joint service."""
