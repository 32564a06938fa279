"""Simulated USB cutters behind pyusb itself: a pyusb backend.

:class:`SimulatedUsbBackend` is a ``usb.backend.IBackend`` that presents one or more
simulated devices (any foldfab simulator behind a :class:`~foldfab.sim.usblink.UsbLink`)
with the descriptors a Silhouette presents: one configuration, one printer-class interface
(held by the kernel's ``usblp`` driver until detached) with a bulk OUT endpoint ``0x01`` and
a bulk IN endpoint ``0x82`` of 64-byte packets, and string descriptors for the
manufacturer, product and serial number.  ``usb.core.find(backend=...)`` then finds them,
and the ``usb://`` handler's real code path runs: find, detach the kernel driver, claim,
bulk transfers with timeouts.

Transfers: a bulk OUT transfer goes a packet at a time, each only once the device has room
for all of it (USB flow control NAKs it until then, and a packet is never split); one that
is not through when the timeout passes raises ``USBTimeoutError`` (the packets before it
arrived).  A bulk IN transfer returns what the device has sent, waiting up to the timeout
for the first byte.  Timeouts are virtual seconds on the simulator's clock (``instant``
time jumps).  After ``disconnect_after`` bytes every call raises ``USBError`` with
``ENODEV``, as libusb does for a pulled cable.
"""

from __future__ import annotations

import array
import errno
from dataclasses import dataclass, field
from types import SimpleNamespace
from urllib.parse import parse_qsl, unquote, urlsplit

import usb.backend
import usb.core

from foldfab.devices.usb import KNOWN_CUTTERS, SILHOUETTE_VENDOR
from foldfab.sim.usblink import Unplugged, UsbLink

PACKET = 64
"""wMaxPacketSize of the bulk endpoints (full speed)."""
EP_OUT, EP_IN = 0x01, 0x82
LIBUSB_ERROR_NO_DEVICE, LIBUSB_ERROR_TIMEOUT = -4, -7
LANGUAGE = 0x0409  # English (United States)


@dataclass
class SimulatedUsbDevice:
    """One simulated device on the bus."""

    link: UsbLink
    vendor: int
    product: int
    serial: str = "SIM0001"
    manufacturer: str = "Graphtec"
    product_name: str = "foldfab simulated cutter"
    address: int = 1
    kernel_driver: bool = True
    """The kernel's printer driver holds the interface (detach it first)."""
    claimed: set[int] = field(default_factory=set)
    configuration: int = 0


class SimulatedUsbBackend(usb.backend.IBackend):
    """pyusb backend presenting simulated devices (see the module docstring)."""

    def __init__(self, devices: list[SimulatedUsbDevice]):
        super().__init__()
        self.devices = devices

    # --- descriptors --------------------------------------------------------------------------
    def enumerate_devices(self):
        return iter(self.devices)

    def get_device_descriptor(self, dev):
        return SimpleNamespace(
            bLength=18, bDescriptorType=1, bcdUSB=0x0200, bDeviceClass=0, bDeviceSubClass=0,
            bDeviceProtocol=0, bMaxPacketSize0=64, idVendor=dev.vendor, idProduct=dev.product,
            bcdDevice=0x0100, iManufacturer=1, iProduct=2, iSerialNumber=3, bNumConfigurations=1,
            address=dev.address, bus=1, port_number=dev.address, port_numbers=(dev.address,), speed=2)

    def get_configuration_descriptor(self, dev, config):
        self._index(config, 1)
        return SimpleNamespace(bLength=9, bDescriptorType=2, wTotalLength=32, bNumInterfaces=1,
                               bConfigurationValue=1, iConfiguration=0, bmAttributes=0xC0,
                               bMaxPower=50, extra_descriptors=[])

    def get_interface_descriptor(self, dev, intf, alt, config):
        self._index(config, 1), self._index(intf, 1), self._index(alt, 1)
        return SimpleNamespace(bLength=9, bDescriptorType=4, bInterfaceNumber=0, bAlternateSetting=0,
                               bNumEndpoints=2, bInterfaceClass=7, bInterfaceSubClass=1,
                               bInterfaceProtocol=2, iInterface=0, extra_descriptors=[])

    def get_endpoint_descriptor(self, dev, ep, intf, alt, config):
        self._index(ep, 2)
        return SimpleNamespace(bLength=7, bDescriptorType=5, bEndpointAddress=(EP_OUT, EP_IN)[ep],
                               bmAttributes=2, wMaxPacketSize=PACKET, bInterval=0, bRefresh=0,
                               bSynchAddress=0, extra_descriptors=[])

    @staticmethod
    def _index(value: int, count: int) -> None:
        if not 0 <= value < count:
            raise IndexError(f"descriptor {value} does not exist")

    # --- handles --------------------------------------------------------------------------------
    def open_device(self, dev):
        self._live(dev)
        return dev

    def close_device(self, dev_handle):
        dev_handle.claimed.clear()

    def set_configuration(self, dev_handle, config_value):
        self._live(dev_handle).configuration = config_value

    def get_configuration(self, dev_handle):
        return self._live(dev_handle).configuration

    def set_interface_altsetting(self, dev_handle, intf, altsetting):
        self._live(dev_handle)

    def claim_interface(self, dev_handle, intf):
        dev = self._live(dev_handle)
        if dev.kernel_driver:
            raise usb.core.USBError("Resource busy", -6, errno.EBUSY)
        dev.claimed.add(intf)

    def release_interface(self, dev_handle, intf):
        dev_handle.claimed.discard(intf)

    def is_kernel_driver_active(self, dev_handle, intf):
        return self._live(dev_handle).kernel_driver

    def detach_kernel_driver(self, dev_handle, intf):
        self._live(dev_handle).kernel_driver = False

    def attach_kernel_driver(self, dev_handle, intf):
        self._live(dev_handle).kernel_driver = True

    def clear_halt(self, dev_handle, ep):
        self._live(dev_handle)

    def reset_device(self, dev_handle):
        self._live(dev_handle)

    def ctrl_transfer(self, dev_handle, bmRequestType, bRequest, wValue, wIndex, data, timeout):
        """Standard GET_DESCRIPTOR for strings; every other request is accepted and ignored."""
        dev = self._live(dev_handle)
        if bmRequestType & 0x80 and bRequest == 6 and wValue >> 8 == 3:
            index = wValue & 0xFF
            text = ["", dev.manufacturer, dev.product_name, dev.serial][index] if index < 4 else ""
            body = LANGUAGE.to_bytes(2, "little") if index == 0 else text.encode("utf-16-le")[:252]
            answer = bytes([2 + len(body), 3]) + body
            count = min(len(answer), len(data))
            data[:count] = array.array("B", answer[:count])
            return count
        return 0 if bmRequestType & 0x80 else len(data)

    # --- transfers ------------------------------------------------------------------------------
    def bulk_write(self, dev_handle, ep, intf, data, timeout):
        dev = self._claimed(dev_handle, intf)
        link, payload, sent = dev.link, bytes(data), 0
        seconds = timeout / 1000 if timeout else None
        try:
            while sent < len(payload):
                packet = payload[sent:sent + PACKET]
                if link.room() < len(packet) and not link.wait(
                        lambda: not link.paper_out and link.fifo_size - len(link.fifo) >= len(packet), seconds):
                    raise usb.core.USBTimeoutError("Operation timed out", LIBUSB_ERROR_TIMEOUT,
                                                   errno.ETIMEDOUT)
                sent += link.accept(packet)
        except Unplugged:
            raise self._gone() from None
        return sent

    def bulk_read(self, dev_handle, ep, intf, buff, timeout):
        dev = self._claimed(dev_handle, intf)
        link = dev.link
        seconds = timeout / 1000 if timeout else None
        try:
            if not link.answering and not link.wait(lambda: link.sim.arrived > 0, seconds):
                raise usb.core.USBTimeoutError("Operation timed out", LIBUSB_ERROR_TIMEOUT,
                                               errno.ETIMEDOUT)
            data = link.take(len(buff))
        except Unplugged:
            raise self._gone() from None
        buff[:len(data)] = array.array("B", data)
        return len(data)

    # --- faults -----------------------------------------------------------------------------------
    @staticmethod
    def _gone() -> usb.core.USBError:
        return usb.core.USBError("No such device (it may have been disconnected)", LIBUSB_ERROR_NO_DEVICE,
                                 errno.ENODEV)

    def _live(self, dev: SimulatedUsbDevice) -> SimulatedUsbDevice:
        if dev.link.sim.disconnected:
            raise self._gone()
        return dev

    def _claimed(self, dev: SimulatedUsbDevice, intf: int) -> SimulatedUsbDevice:
        self._live(dev)
        if intf not in dev.claimed:
            raise usb.core.USBError("Interface not claimed", -5, errno.ENOENT)
        return dev


DEFAULT_PRODUCT = 0x1137
"""The product id of a simulated profile no known cutter names (the Cameo 4's)."""


def simulated_cutter(spec: str, address: int = 1) -> SimulatedUsbDevice:
    """A simulated USB cutter from ``DEVICE?option=value&...`` (a profile name or path and the
    simulator's options, as in ``sim://``), with the USB ids of the known cutter whose profile
    it is (:data:`foldfab.devices.usb.KNOWN_CUTTERS`), else a Silhouette's."""
    from foldfab.devices import load_device
    from foldfab.sim import create_simulator, parse_options

    parts = urlsplit(f"sim://{spec}")
    device = load_device(unquote(parts.netloc + parts.path))
    options = parse_options(parse_qsl(parts.query, keep_blank_values=True), f"simulated USB cutter {spec}")
    vendor, product = next((ids for ids, cutter in KNOWN_CUTTERS.items() if cutter.profile == device.name),
                           (SILHOUETTE_VENDOR, DEFAULT_PRODUCT))
    return SimulatedUsbDevice(UsbLink(create_simulator(device, options)), vendor, product,
                              serial=f"SIM{address:04d}", address=address)
