"""Small MJCF scenes shared by several test modules."""

#: A 30 cm aluminium plate on the floor and a 2 cm ball 25 cm above it (1 ms steps; the
#: contacts' solref gives a restitution of about 0.6). The ball's first impact is at ~0.2 s.
PLATE_BALL_XML = """
<mujoco>
  <option timestep="0.001"/>
  <custom><text name="mjsound:plate" data="aluminium"/></custom>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 .1"/>
    <geom name="plate" type="box" size="0.15 0.15 0.005" pos="0 0 0.005" solref="-1e5 -120"/>
    <body name="ball" pos="0 0 0.25"><freejoint/>
      <geom name="ball" type="sphere" size="0.02" solref="-1e5 -120"/></body>
  </worldbody>
</mujoco>"""

#: A static "table": the anchor geom is the leg (listed first, turned 30 degrees about z), the
#: ball falls on the top, which is the body's second geom.
TABLE_XML = """
<mujoco>
  <option timestep="0.001"/>
  <custom>{custom}</custom>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 .1"/>
    <body name="table" pos="0.1 0 0.3" euler="0 0 10">
      <geom name="leg" type="box" size="0.01 0.02 0.14" pos="0.15 0.05 -0.15" euler="0 0 30" density="{density}"/>
      <geom name="top" type="box" size="0.2 0.1 0.01" density="{density}"/>
      <geom name="look" type="cylinder" size="0.12 0.02" pos="0 0 0.02" contype="0" conaffinity="0" group="1"/>
    </body>
    <body name="ball" pos="0.05 0.02 0.5"><freejoint/><geom name="ball" type="sphere" size="0.01"/></body>
  </worldbody>
</mujoco>"""


def table_model(custom="", density=1000):
    import mujoco

    return mujoco.MjModel.from_xml_string(TABLE_XML.format(custom=custom, density=density))
