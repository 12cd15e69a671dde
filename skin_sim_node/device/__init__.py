"""The device side: Touch bridge, simulated device, mock tool, passivity controller."""
