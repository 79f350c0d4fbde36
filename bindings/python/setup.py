"""The wheel carries a compiled extension: mark it as platform specific (cpXY-cpXY-linux_*)."""
from setuptools import Distribution, setup


class BinaryDistribution(Distribution):
    def has_ext_modules(self):
        return True


setup(distclass=BinaryDistribution)
