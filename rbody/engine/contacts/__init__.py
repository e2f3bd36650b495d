"""Contacts between geoms in the rigid limit: the narrow phase (geometry.py) whose distances and normals the
constraint layer (rbody.engine.constraints) takes as gap functions of unilateral rows with Coulomb friction."""
