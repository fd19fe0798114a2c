"""Qt dialogs of the plugin (control/check point measurement, residual views)."""
