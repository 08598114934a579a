"""The force and moment a grabber's pad exerts on the box, summed over their MuJoCo contacts."""

import mujoco
import numpy as np
from sim_bridge.scene import site_pose


def pad_wrench(model, data, pad, box, tool_site):
    """
    Return (force_world (3,) [N], torque_world (3,) [N m] about the tool point, in_contact).

    pad, box: geom ids; tool_site: the site id of the arm's tool point.
    """
    p_world_tool, _ = site_pose(data, tool_site)
    force_world = np.zeros(3)
    torque_world = np.zeros(3)
    in_contact = False
    contact_force = np.zeros(6)
    for contact_id in range(data.ncon):
        contact = data.contact[contact_id]
        if {int(contact.geom1), int(contact.geom2)} != {pad, box}:
            continue
        mujoco.mj_contactForce(model, data, contact_id, contact_force)
        # Contact frame rows: normal (from geom1 to geom2), two tangents; the force is the
        # one geom1 exerts on geom2.
        force = contact.frame.reshape(3, 3).T @ contact_force[:3]
        if int(contact.geom1) != pad:
            force = -force
        force_world += force
        torque_world += np.cross(contact.pos - p_world_tool, force)
        in_contact = True
    return force_world, torque_world, in_contact
