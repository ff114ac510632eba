// Everything of the SocketCAN backend that does not need a CAN-capable kernel.
#include "shared/drivers/socketcan/socketcan_frame.h"

#include <gtest/gtest.h>
#include <linux/can/error.h>

#include <cstring>

#include "shared/drivers/socketcan/socketcan_bus.h"
#include "shared/hal/can_error.h"

namespace idi::drivers {
namespace {

can_frame KernelFrame(canid_t id, std::initializer_list<uint8_t> bytes) {
  can_frame f;
  std::memset(&f, 0, sizeof(f));
  f.can_id = id;
  f.len = static_cast<uint8_t>(bytes.size());
  std::size_t i = 0;
  for (uint8_t b : bytes) f.data[i++] = b;
  return f;
}

TEST(SocketCanFrameTest, StandardExtendedAndRemoteFramesBothWays) {
  hal::CanFrame f;
  f.id = 0x413;
  f.dlc = 8;
  f.data = {0xFB, 0x68, 0x04, 0x00, 0x00, 0x32, 0x00, 0x0F};
  Result<can_frame> k = ToSocketCanFrame(f);
  ASSERT_TRUE(k.ok());
  EXPECT_EQ(k->can_id, 0x413u);
  EXPECT_EQ(k->len, 8);
  EXPECT_EQ(std::memcmp(k->data, f.data.data(), 8), 0);
  const hal::CanFrame back = FromSocketCanFrame(*k, 123);
  EXPECT_EQ(back.id, 0x413u);
  EXPECT_EQ(back.data, f.data);
  EXPECT_EQ(back.timestamp_ns, 123);
  EXPECT_FALSE(back.extended || back.rtr || back.error);

  hal::CanFrame ext;
  ext.id = 0x1ABCDE01;
  ext.extended = true;
  ext.dlc = 2;
  ext.data[0] = 0xAA;
  k = ToSocketCanFrame(ext);
  ASSERT_TRUE(k.ok());
  EXPECT_EQ(k->can_id, 0x1ABCDE01u | CAN_EFF_FLAG);
  const hal::CanFrame ext_back = FromSocketCanFrame(*k, 0);
  EXPECT_TRUE(ext_back.extended);
  EXPECT_EQ(ext_back.id, 0x1ABCDE01u);
  EXPECT_EQ(ext_back.dlc, 2);

  hal::CanFrame rtr;
  rtr.id = 0x123;
  rtr.rtr = true;
  rtr.dlc = 4;
  k = ToSocketCanFrame(rtr);
  ASSERT_TRUE(k.ok());
  EXPECT_EQ(k->can_id, 0x123u | CAN_RTR_FLAG);
  EXPECT_TRUE(FromSocketCanFrame(*k, 0).rtr);
  EXPECT_EQ(FromSocketCanFrame(*k, 0).dlc, 4);
}

TEST(SocketCanFrameTest, RejectsWhatNoControllerSends) {
  hal::CanFrame f;
  f.id = 0x800;
  EXPECT_EQ(ToSocketCanFrame(f).status().code(), StatusCode::kInvalidArgument);
  f.id = 0x20000000;
  f.extended = true;
  EXPECT_EQ(ToSocketCanFrame(f).status().code(), StatusCode::kInvalidArgument);
  f = {};
  f.dlc = 9;
  EXPECT_NE(ToSocketCanFrame(f).status().message().find("DLC 9"), std::string::npos);
  f = {};
  f.error = true;
  EXPECT_EQ(ToSocketCanFrame(f).status().code(), StatusCode::kInvalidArgument);
  // A DLC above 8 from the kernel (len8_dlc) is clamped, never read past the data.
  can_frame k = KernelFrame(0x100, {1, 2, 3, 4, 5, 6, 7, 8});
  k.len = 15;
  EXPECT_EQ(FromSocketCanFrame(k, 0).dlc, 8);
}

TEST(SocketCanErrorFrameTest, BusOffRestartAndControllerStatesDecode) {
  const hal::CanFrame off = FromSocketCanFrame(KernelFrame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0}), 5);
  EXPECT_TRUE(off.error);
  EXPECT_EQ(off.id, static_cast<uint32_t>(CAN_ERR_BUSOFF));
  hal::CanErrorInfo info = hal::DecodeCanError(off);
  EXPECT_TRUE(info.bus_off);
  EXPECT_TRUE(info.has_state);
  EXPECT_EQ(info.state, hal::CanControllerState::kBusOff);
  EXPECT_EQ(hal::DescribeCanError(info), "bus-off");

  info = hal::DecodeCanError(FromSocketCanFrame(
      KernelFrame(CAN_ERR_FLAG | CAN_ERR_CRTL | CAN_ERR_CNT, {0, CAN_ERR_CRTL_TX_PASSIVE, 0, 0, 0, 0, 130, 7}), 0));
  EXPECT_EQ(info.state, hal::CanControllerState::kErrorPassive);
  EXPECT_TRUE(info.has_counters);
  EXPECT_EQ(info.tx_error_count, 130);
  EXPECT_EQ(info.rx_error_count, 7);
  EXPECT_NE(hal::DescribeCanError(info).find("error-passive"), std::string::npos);

  info = hal::DecodeCanError(FromSocketCanFrame(KernelFrame(CAN_ERR_FLAG | CAN_ERR_CRTL, {0, CAN_ERR_CRTL_RX_WARNING, 0, 0, 0, 0, 0, 0}), 0));
  EXPECT_EQ(info.state, hal::CanControllerState::kErrorWarning);
  info = hal::DecodeCanError(FromSocketCanFrame(KernelFrame(CAN_ERR_FLAG | CAN_ERR_RESTARTED, {0, 0, 0, 0, 0, 0, 0, 0}), 0));
  EXPECT_TRUE(info.restarted);
  EXPECT_EQ(info.state, hal::CanControllerState::kErrorActive);
  info = hal::DecodeCanError(FromSocketCanFrame(
      KernelFrame(CAN_ERR_FLAG | CAN_ERR_PROT | CAN_ERR_ACK, {0, 0, CAN_ERR_PROT_STUFF, CAN_ERR_PROT_LOC_ACK, 0, 0, 0, 0}), 0));
  EXPECT_TRUE(info.no_ack);
  EXPECT_FALSE(info.has_state);
  EXPECT_EQ(info.protocol_type, CAN_ERR_PROT_STUFF);
  EXPECT_EQ(info.protocol_location, CAN_ERR_PROT_LOC_ACK);
  info = hal::DecodeCanError(FromSocketCanFrame(KernelFrame(CAN_ERR_FLAG | CAN_ERR_CRTL, {0, CAN_ERR_CRTL_RX_OVERFLOW, 0, 0, 0, 0, 0, 0}), 0));
  EXPECT_TRUE(info.rx_overflow);
  EXPECT_FALSE(info.has_state);
}

TEST(SocketCanFilterTest, KernelFiltersKeepStandardAndExtendedApart) {
  const can_filter std_filter = ToKernelFilter({0x400, 0x7F8, false, false});
  EXPECT_EQ(std_filter.can_id, 0x400u);
  EXPECT_EQ(std_filter.can_mask, 0x7F8u | CAN_EFF_FLAG | CAN_RTR_FLAG);
  auto passes = [](const can_filter& f, canid_t id) {
    const bool match = (id & f.can_mask) == (f.can_id & f.can_mask & ~CAN_INV_FILTER);
    return (f.can_id & CAN_INV_FILTER) ? !match : match;
  };
  EXPECT_TRUE(passes(std_filter, 0x403));
  EXPECT_FALSE(passes(std_filter, 0x413));
  EXPECT_FALSE(passes(std_filter, 0x403 | CAN_EFF_FLAG)) << "an extended id with the same low bits";
  const can_filter ext = ToKernelFilter({0x18FF0000, 0x1FFF0000, true, false});
  EXPECT_TRUE(passes(ext, 0x18FF1234 | CAN_EFF_FLAG));
  EXPECT_FALSE(passes(ext, 0x234));
  const can_filter inv = ToKernelFilter({0x413, 0x7FF, false, true});
  EXPECT_TRUE(inv.can_id & CAN_INV_FILTER);
  EXPECT_FALSE(passes(inv, 0x413));
  EXPECT_TRUE(passes(inv, 0x400));
}

TEST(SocketCanOptionsTest, ChecksNamesFiltersAndMasks) {
  SocketCanOptions o;
  EXPECT_TRUE(o.Check().ok());
  o.interface = "";
  EXPECT_EQ(o.Check().code(), StatusCode::kInvalidArgument);
  o.interface = "a_very_long_name_x";
  EXPECT_NE(o.Check().message().find("a_very_long_name_x"), std::string::npos);
  o.interface = "can0";
  o.filters = {{0x800, 0x7FF, false, false}};
  EXPECT_EQ(o.Check().code(), StatusCode::kInvalidArgument);
  o.filters = {};
  o.error_mask = 0x1000;
  EXPECT_EQ(o.Check().code(), StatusCode::kInvalidArgument);
}

TEST(SocketCanOpenTest, AMissingInterfaceOrKernelSupportIsAClearError) {
  SocketCanOptions o;
  o.interface = "idi_nocan9";
  Result<std::unique_ptr<SocketCanBus>> bus = SocketCanBus::Open(o);
  ASSERT_FALSE(bus.ok());
  // NotFound on a kernel with SocketCAN; IoError naming the missing modules on one without.
  EXPECT_TRUE(bus.status().code() == StatusCode::kNotFound || bus.status().code() == StatusCode::kIoError);
  EXPECT_NE(bus.status().message().find("idi_nocan9"), std::string::npos) << bus.status().message();
}

}  // namespace
}  // namespace idi::drivers
