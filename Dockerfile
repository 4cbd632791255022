# stiffcomp: the compensation service and the model tools in one image.
#   docker build -t stiffcomp .
#   docker run --rm -p 5020:5020 stiffcomp                      # the service, replay source, Modbus on 5020
#   docker run --rm -v "$PWD:/data" stiffcomp fit config/models/kr125_6dof.yaml /data/campaign.csv --json
# For the real-time cycle give the container a CPU of its own and permission to raise its priority:
#   docker run --rm --cpuset-cpus 1 --cap-add SYS_NICE -p 5020:5020 stiffcomp run --config /data/site.yaml
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 MPLBACKEND=Agg
WORKDIR /opt/stiffcomp

COPY pyproject.toml README.md ./
COPY stiffness ./stiffness
COPY service ./service
COPY plc_interface ./plc_interface
COPY tools ./tools
COPY hil ./hil
COPY config ./config
COPY examples ./examples
# The service binds 127.0.0.1 by default; in a container it must listen on all interfaces.
RUN pip install --no-cache-dir ".[parquet]" \
 && sed -i 's/^  host: 127.0.0.1/  host: 0.0.0.0/' config/default.yaml \
 && useradd --system --home-dir /opt/stiffcomp stiffcomp
USER stiffcomp

EXPOSE 5020
ENTRYPOINT ["stiffcomp"]
CMD ["run", "--config", "config/default.yaml"]
