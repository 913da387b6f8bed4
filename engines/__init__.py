"""Built-in cleaning engines, registered through the ``mocap_workbench.engines`` entry points."""
