# air-sitl in one image: the simulator, the zenoh router, the camera bridge, the example localizer.
# Build from the repository root:  docker build -t air-sitl .   (or: docker compose build)
FROM python:3.11-slim

ENV PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /opt/air-sitl
# Every dependency ships manylinux wheels (jsbsim, opencv-python-headless, rasterio with GDAL,
# eclipse-zenoh, mavsdk): no compiler and no system libraries needed.
# EXTRAS: optional extras, for example --build-arg EXTRAS="[ray]" (docker-compose's Ray nodes).
ARG EXTRAS=""
COPY pyproject.toml README.md ./
COPY air_sitl ./air_sitl
RUN pip install ".${EXTRAS}"
COPY bridges ./bridges
COPY missions ./missions
COPY examples ./examples

# zenoh (router), MAVLink over TCP (QGroundControl: Comm Links -> TCP, host 127.0.0.1:5760)
EXPOSE 7447 5760
CMD ["air-sitl", "--help"]
