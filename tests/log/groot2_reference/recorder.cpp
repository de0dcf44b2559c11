// Records what BehaviorTree.CPP's own Groot2Publisher answers for tree.xml, as a Groot2 client would ask.
//
// Usage: groot2_recorder TREE.xml OUT.json [PORT [TICKS]]
// Registers Countdown and Tally (as tests/log/groot2_support.py writes them), builds the tree, starts
// BT::Groot2Publisher on PORT (default 22667; PORT + 1 for its publisher), then on a REQ socket:
// FULLTREE, STATUS, TOGGLE_RECORDING start; for each of TICKS ticks (default 6): tickExactlyOnce (one root tick,
// as chaser-bt's runner ticks: no re-tick on a wake-up signal), STATUS,
// GET_TRANSITIONS; then BLACKBOARD, the hook and error requests. Every request and reply part is written to
// OUT.json as hex.
//
// Usage: groot2_recorder --fulltree TREE.xml MODELS.json OUT.xml [PORT]
// Registers a stand-in for every node in MODELS.json (`python tests/log/groot2_support.py`: chaser-bt's
// own nodes with their kinds and ports), builds TREE.xml (its includes too) and writes the FULLTREE
// reply's XML to OUT.xml as it came.
#include <behaviortree_cpp/bt_factory.h>
#include <behaviortree_cpp/contrib/json.hpp>
#include <behaviortree_cpp/loggers/groot2_protocol.h>
#include <behaviortree_cpp/loggers/groot2_publisher.h>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include "stand_ins.hpp"

#include <fstream>
#include <iostream>
#include <string>
#include <vector>

namespace
{
using stand_ins::Countdown;
using stand_ins::Tally;

std::string hex(const std::string& bytes)
{
  static const char* digits = "0123456789abcdef";
  std::string out;
  for(unsigned char c : bytes)
  {
    out += digits[c >> 4];
    out += digits[c & 15];
  }
  return out;
}
}  // namespace

std::string askFullTree(unsigned port)
{
  zmq::context_t context;
  zmq::socket_t client(context, ZMQ_REQ);
  client.set(zmq::sockopt::rcvtimeo, 5000);
  client.connect("tcp://127.0.0.1:" + std::to_string(port));
  BT::Monitor::RequestHeader header(BT::Monitor::RequestType::FULLTREE);
  zmq::multipart_t request;
  request.addstr(BT::Monitor::SerializeHeader(header));
  request.send(client);
  zmq::multipart_t reply;
  if(!reply.recv(client) || reply.size() != 2)
  {
    throw std::runtime_error("no FULLTREE reply");
  }
  return reply[1].to_string();
}

int recordFullTree(const std::string& tree_path, const std::string& models_path,
                   const std::string& out_path, unsigned port)
{
  std::ifstream models_file(models_path);
  const auto models = nlohmann::json::parse(models_file);
  BT::BehaviorTreeFactory factory;
  for(const auto& [id, model] : models.items())
  {
    BT::PortsList ports;
    for(const auto& port_model : model.at("ports"))
    {
      const auto name = port_model.at("name").get<std::string>();
      const auto description = port_model.at("description").get<std::string>();
      const bool input = port_model.at("direction") == "input";
      if(port_model.at("default").is_null())
      {
        ports.insert(input ? BT::InputPort<BT::AnyTypeAllowed>(name, description) :
                             BT::OutputPort<BT::AnyTypeAllowed>(name, description));
      }
      else
      {
        const auto value = port_model.at("default").get<std::string>();
        ports.insert(input ? BT::InputPort<BT::AnyTypeAllowed>(name, value, description) :
                             BT::OutputPort<BT::AnyTypeAllowed>(name, value, description));
      }
    }
    const auto kind = model.at("kind").get<std::string>();
    if(kind == "Decorator")
    {
      factory.registerSimpleDecorator(
          id, [](BT::NodeStatus status, BT::TreeNode&) { return status; }, ports);
    }
    else if(kind == "Condition")
    {
      factory.registerSimpleCondition(
          id, [](BT::TreeNode&) { return BT::NodeStatus::SUCCESS; }, ports);
    }
    else
    {
      factory.registerSimpleAction(
          id, [](BT::TreeNode&) { return BT::NodeStatus::SUCCESS; }, ports);
    }
  }
  auto tree = factory.createTreeFromFile(tree_path);
  BT::Groot2Publisher publisher(tree, port);
  std::ofstream(out_path) << askFullTree(port);
  std::cout << "wrote the FULLTREE of " << tree_path << " to " << out_path << "\n";
  return 0;
}

int main(int argc, char** argv)
{
  if(argc >= 5 && std::string(argv[1]) == "--fulltree")
  {
    return recordFullTree(argv[2], argv[3], argv[4], argc > 5 ? std::stoul(argv[5]) : 22667);
  }
  if(argc < 3)
  {
    std::cerr << "usage: groot2_recorder TREE.xml OUT.json [PORT [TICKS]]\n"
                 "       groot2_recorder --fulltree TREE.xml MODELS.json OUT.xml [PORT]\n";
    return 2;
  }
  const unsigned port = argc > 3 ? std::stoul(argv[3]) : 22667;
  const int ticks = argc > 4 ? std::stoi(argv[4]) : 6;

  BT::BehaviorTreeFactory factory;
  factory.registerNodeType<Countdown>("Countdown");
  factory.registerNodeType<Tally>("Tally");
  auto tree = factory.createTreeFromFile(argv[1]);
  BT::Groot2Publisher publisher(tree, port);

  zmq::context_t context;
  zmq::socket_t client(context, ZMQ_REQ);
  client.set(zmq::sockopt::rcvtimeo, 5000);
  client.connect("tcp://127.0.0.1:" + std::to_string(port));

  nlohmann::json exchanges = nlohmann::json::array();
  uint32_t next_id = 0x01020300;
  auto ask = [&](const std::string& name, std::vector<std::string> parts) {
    zmq::multipart_t request;
    for(const auto& part : parts)
    {
      request.addstr(part);
    }
    request.send(client);
    zmq::multipart_t reply;
    if(!reply.recv(client))
    {
      throw std::runtime_error("no reply to " + name);
    }
    nlohmann::json entry;
    entry["name"] = name;
    entry["request"] = nlohmann::json::array();
    for(const auto& part : parts)
    {
      entry["request"].push_back(hex(part));
    }
    entry["reply"] = nlohmann::json::array();
    for(size_t i = 0; i < reply.size(); i++)
    {
      entry["reply"].push_back(hex(reply[i].to_string()));
    }
    exchanges.push_back(entry);
  };
  auto header = [&](BT::Monitor::RequestType type) {
    BT::Monitor::RequestHeader h(type);
    h.unique_id = next_id++;  // fixed ids, so the recording is reproducible
    return BT::Monitor::SerializeHeader(h);
  };
  using RT = BT::Monitor::RequestType;

  ask("fulltree", { header(RT::FULLTREE) });
  ask("status_0", { header(RT::STATUS) });
  ask("recording_start", { header(RT::TOGGLE_RECORDING), "start" });
  for(int tick = 1; tick <= ticks; tick++)
  {
    tree.tickExactlyOnce();
    ask("status_" + std::to_string(tick), { header(RT::STATUS) });
    ask("transitions_" + std::to_string(tick), { header(RT::GET_TRANSITIONS) });
  }
  ask("recording_stop", { header(RT::TOGGLE_RECORDING), "stop" });
  ask("hooks_dump", { header(RT::HOOKS_DUMP) });
  ask("remove_all_hooks", { header(RT::REMOVE_ALL_HOOKS) });
  ask("disable_all_hooks", { header(RT::DISABLE_ALL_HOOKS) });
  ask("hook_remove", { header(RT::HOOK_REMOVE), R"({"uid": 2, "position": 0})" });
  ask("hook_remove_one_part", { header(RT::HOOK_REMOVE) });
  ask("blackboard", { header(RT::BLACKBOARD), "Main;tail;outbound;nope" });
  ask("blackboard_unknown", { header(RT::BLACKBOARD), "nope" });
  ask("blackboard_one_part", { header(RT::BLACKBOARD) });
  ask("unknown_type", { header(static_cast<RT>('Z')) });
  ask("short_header", { std::string("\x02T\x01\x02\x03", 5) });

  std::ofstream out(argv[2]);
  out << exchanges.dump(1) << "\n";
  std::cout << "wrote " << exchanges.size() << " exchanges to " << argv[2] << "\n";
  return 0;
}
