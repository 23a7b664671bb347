"""The networks (torch): U-Nets, losses, training, inference."""
