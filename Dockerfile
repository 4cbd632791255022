# stiffcomp: the compensation service and the model tools in one image (docs/deploy.md).
#
#   make image                                # docker build --network=host -t stiffcomp .
#   docker run -d --name stiffcomp --restart on-failure:5 --network host -v "$PWD/site:/etc/stiffcomp:ro" stiffcomp
#
# The service reads /etc/stiffcomp/service.yaml: mount your site's folder there. The image carries a
# starting config at that path (config/default.yaml, paths absolute, servers on all interfaces):
#   docker run --rm --entrypoint cat stiffcomp /etc/stiffcomp/service.yaml > site/service.yaml
#
# Without registry access, build from a local base made of Debian packages (docs/deploy.md):
#   docker build --network=host --build-arg BASE=stiffcomp-base:bookworm -t stiffcomp .
#
# Two stages: the build stage trusts the site's CA certificates, runs pip and compiles the cycle; the
# runtime stage starts again from the base and takes only the virtual environment, the project and the
# compiled cycle, so the build's certificates, pip, setuptools and the packages' test folders never
# reach the shipped image (nor does the base's own pip, where it has one: it is uninstalled).
ARG BASE=python:3.11-slim

# -- build ------------------------------------------------------------------------------------------
FROM ${BASE} AS build

# pip's index inside the build; empty means pypi.org. A site mirror: --build-arg PIP_INDEX_URL=...
ARG PIP_INDEX_URL=
ARG PIP_EXTRA_INDEX_URL=
ARG PIP_TRUSTED_HOST=
# optional extras of the project, e.g. "parquet" (pyarrow, for .parquet measurement files)
ARG EXTRAS=parquet

ENV PYTHONDONTWRITEBYTECODE=1 VIRTUAL_ENV=/opt/venv PATH=/opt/venv/bin:$PATH
WORKDIR /opt/stiffcomp

# Site CA certificates (*.crt) for a TLS-inspecting proxy between the build and the index: `make image`
# copies them from CA_CERTS_DIR into deploy/ca-certificates/ (empty by default, never committed).
COPY deploy/ca-certificates/ /usr/local/share/ca-certificates/stiffcomp/
RUN if ls /usr/local/share/ca-certificates/stiffcomp/*.crt >/dev/null 2>&1; then update-ca-certificates; fi

COPY pyproject.toml README.md ./
COPY stiffness ./stiffness
COPY service ./service
COPY io_process ./io_process
COPY robot_road ./robot_road
COPY plc_link ./plc_link
COPY io_base ./io_base
COPY tools ./tools
COPY hil ./hil
COPY cell ./cell
COPY st_runtime ./st_runtime
COPY config ./config
COPY examples ./examples

# A virtual environment works alike on python:3.11-slim and on Debian's python3 (which refuses
# system-wide pip installs). Installed editable so that config/ stays beside the code: the package
# finds config/default.yaml, the models and the register map where the source tree has them.
# Then everything only the build needs goes: pip, setuptools, wheel, the egg-info, the packages' tests.
# Last, the bytecode of the whole venv and the project: the service runs as a user who cannot write it
# (and with PYTHONDONTWRITEBYTECODE), so whatever is not compiled here is compiled again at every start
# of every command, the HEALTHCHECK's probe included (docs/deploy.md has the figures).
RUN python3 -m venv "$VIRTUAL_ENV" \
 && export PIP_CERT=/etc/ssl/certs/ca-certificates.crt PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1 \
           PIP_INDEX_URL="${PIP_INDEX_URL:-https://pypi.org/simple}" PIP_EXTRA_INDEX_URL PIP_TRUSTED_HOST \
 && pip install --upgrade pip \
 && pip install -e ".${EXTRAS:+[$EXTRAS]}" \
 && pip uninstall -y -q pip setuptools wheel \
 && rm -rf ./*.egg-info \
 && find "$VIRTUAL_ENV" -depth -type d -name tests -path "*/site-packages/*" -exec rm -rf {} + \
 && python3 -m compileall -q -j 0 "$VIRTUAL_ENV" stiffness io_base plc_link robot_road io_process service cell st_runtime tools hil

# The compiled cycle (numba) of every shipped model, compiled into one folder: the generated modules
# ($STIFFCOMP_KERNEL_CACHE) and numba's cache of every compiled function, the kernel's own included
# ($NUMBA_CACHE_DIR; by default numba writes beside the source, which the service's user cannot). The
# runtime stage takes the folder as it is, owned by that user, so the service's first cycle loads what was
# compiled here and never waits for a compiler (docs/deploy.md#the-compiled-cycle).
ENV STIFFCOMP_KERNEL_CACHE=/var/cache/stiffcomp/kernels NUMBA_CACHE_DIR=/var/cache/stiffcomp/numba
RUN python3 -m service.kernel.warm

# -- runtime ----------------------------------------------------------------------------------------
FROM ${BASE}

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 MPLBACKEND=Agg \
    VIRTUAL_ENV=/opt/venv PATH=/opt/venv/bin:$PATH \
    STIFFCOMP_KERNEL_CACHE=/var/cache/stiffcomp/kernels NUMBA_CACHE_DIR=/var/cache/stiffcomp/numba
WORKDIR /opt/stiffcomp

# pinocchio's wheels need OpenMP's runtime; python:3.11-slim lacks it (a Debian base made as in
# docs/deploy.md includes it, so an offline build never reaches this apt-get)
RUN if ! ldconfig -p | grep -q libgomp.so.1; then \
      apt-get update && apt-get install -y --no-install-recommends libgomp1 && rm -rf /var/lib/apt/lists/*; \
    fi
# no pip in the shipped image: python:3.11-slim's own Python carries one, a Debian or Ubuntu base may have
# python3-pip (which pip refuses to uninstall: PEP 668), the Debian base of docs/deploy.md has none; each is
# removed by the tool that installed it (deploy/remove_pip.sh). Run before the venv arrives, so python3 is the base's
COPY deploy/remove_pip.sh /tmp/remove_pip.sh
RUN sh /tmp/remove_pip.sh && rm /tmp/remove_pip.sh

RUN useradd --system --no-create-home --home-dir /opt/stiffcomp --shell /usr/sbin/nologin stiffcomp
COPY --from=build /opt/venv /opt/venv
COPY --from=build /opt/stiffcomp /opt/stiffcomp
# the warmed cycle, the user's: numba opens its cache only where it may write (a CPU other than the
# build machine's, or a site model with other laws, compiles at the first start and is kept there)
COPY --from=build --chown=stiffcomp:stiffcomp /var/cache/stiffcomp /var/cache/stiffcomp

# The starting config: servers on all interfaces, and the Prometheus endpoint on (docs/deploy.md#metrics:
# it is served by the I/O process, never by the cycle, on the HTTP port the health probes open anyway)
RUN mkdir -p /etc/stiffcomp \
 && python3 -c "from pathlib import Path; from hil.testing import write_config; \
write_config(Path('/etc/stiffcomp'), {'plc': {'host': '0.0.0.0', 'port': 5020}, \
  'ads': {'host': '0.0.0.0', 'port': 48898}, 'monitoring': {'host': '0.0.0.0', 'port': 9020, 'metrics': True}})"
USER stiffcomp

# Modbus TCP, ADS (AMS/TCP), HTTP health + metrics, Modbus/TCP Security (plc.tls, off until the site's
# certificates are mounted; docs/security.md: as an unprivileged user 802 binds on a bridge network only), and
# the robot road's UDP ports as the shipped robot sides name them (KUKA RSI 49152, ABB EGM 6511; docs/robot.md)
EXPOSE 5020 48898 9020 802 49152/udp 6511/udp
VOLUME ["/etc/stiffcomp"]
# Liveness: the cycle count rises and the I/O process answers (/health/live). Not /health, whose exceed
# bound a busy host can cross for a while: a restart would lose the tare, the hysteresis state and the
# PLC session for nothing. The probe takes tenths of a second in the image (docs/deploy.md#the-probes-cost).
HEALTHCHECK --interval=5s --timeout=3s --start-period=30s --retries=3 \
    CMD ["stiffcomp", "health", "--live", "--config", "/etc/stiffcomp/service.yaml"]
# `docker stop` sends SIGTERM: the service ramps the correction to zero and exits with code 0
STOPSIGNAL SIGTERM
ENTRYPOINT ["stiffcomp"]
CMD ["run", "--config", "/etc/stiffcomp/service.yaml"]
